"""Problem definitions: friction laws, loading, the spring-slider with mass, and the paper's presets."""

from problems.files import load_problem
from problems.friction import LAWS, AgingLaw, FrictionLaw, SlipLaw, law_from_name
from problems.loading import ConstantLoading, TwoSpeedLoading, event_thresholds
from problems.presets import PRESET_NAMES, WINDOWS, aging_best_fit, paper_example, preset, window
from problems.slider import (BalancedStart, InitialState, Nondimensional, SpringSlider,
                             balanced_initial_state, steady_initial_state, variant,
                             variant_fields)
from problems.stability import (characteristic_roots, critical_stiffness, growth_rate,
                                neutral_frequency)

__all__ = [
    "load_problem", "LAWS", "AgingLaw", "FrictionLaw", "SlipLaw", "law_from_name",
    "ConstantLoading", "TwoSpeedLoading", "event_thresholds",
    "PRESET_NAMES", "WINDOWS", "aging_best_fit", "paper_example", "preset", "window",
    "BalancedStart", "InitialState", "Nondimensional", "SpringSlider", "balanced_initial_state",
    "steady_initial_state", "variant", "variant_fields",
    "characteristic_roots", "critical_stiffness", "growth_rate", "neutral_frequency",
]
