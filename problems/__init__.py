"""Problem definitions: friction laws, loading, the spring-slider with mass, and the paper's presets."""

from problems.files import load_problem
from problems.friction import (LAWS, AgingLaw, FrictionLaw, NagataLaw, SlipLaw, law_from_name,
                               law_parameters)
from problems.loading import (ConstantLoading, LoadHistory, TwoSpeedLoading, event_thresholds,
                              slide_hold_slide, velocity_step)
from problems.presets import (PRESET_NAMES, WINDOWS, aging_best_fit, paper_example, preset,
                              slide_hold_slide_test, velocity_step_test, window)
from problems.slider import (BalancedStart, InitialState, Nondimensional, SpringSlider,
                             balanced_initial_state, steady_initial_state, variant,
                             variant_fields)
from problems.stability import (characteristic_polynomial, characteristic_roots,
                                critical_stiffness, growth_rate, growth_rates,
                                neutral_frequency)

__all__ = [
    "load_problem", "LAWS", "AgingLaw", "FrictionLaw", "NagataLaw", "SlipLaw", "law_from_name",
    "law_parameters",
    "ConstantLoading", "LoadHistory", "TwoSpeedLoading", "event_thresholds", "slide_hold_slide",
    "velocity_step", "PRESET_NAMES", "WINDOWS", "aging_best_fit", "paper_example", "preset",
    "window", "velocity_step_test", "slide_hold_slide_test",
    "BalancedStart", "InitialState", "Nondimensional", "SpringSlider", "balanced_initial_state",
    "steady_initial_state", "variant", "variant_fields",
    "characteristic_polynomial", "characteristic_roots", "critical_stiffness", "growth_rate",
    "growth_rates", "neutral_frequency",
]
