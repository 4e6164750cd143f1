# One command sets everything up and runs: `make test` (the test suite) or `make reproduce`
# (brings results/ up to date). Both are idempotent: system packages are installed only if
# missing, .venv is created once and re-synced when pyproject.toml or requirements.lock changes.

PYTHON   ?= python3
VENV     := .venv
PY       := $(VENV)/bin/python
APT_PKGS := gfortran libsundials-dev pkg-config cmake
STAMP    := $(VENV)/.installed
WARM     := $(VENV)/.compiled
# the tests run in this many processes (pytest-xdist): the cores, at most 4 (each process
# imports the whole stack); `make test JOBS=1` runs them in one
JOBS     ?= $(shell n=$$(nproc 2>/dev/null || echo 1); [ $$n -gt 4 ] && n=4; echo $$n)

.PHONY: all setup system-packages numba-cache warm test test-slow docs reproduce reproduce-full bench clean

# `make`: install, then compile every kernel ahead, so that a first run does not wait for it
all: setup numba-cache warm

setup: $(STAMP)

system-packages:
	@missing=""; for p in $(APT_PKGS); do \
	  dpkg-query -W -f='$${Status}' $$p 2>/dev/null | grep -q "install ok installed" || missing="$$missing $$p"; \
	done; \
	if [ -n "$$missing" ]; then \
	  echo "installing system packages:$$missing"; \
	  if [ "$$(id -u)" -ne 0 ]; then SUDO=sudo; else SUDO=; fi; \
	  $$SUDO apt-get update -qq && DEBIAN_FRONTEND=noninteractive $$SUDO apt-get install -y -qq $$missing; \
	fi

# every extra and the test group, at the versions of requirements.lock
$(STAMP): pyproject.toml requirements.lock | system-packages
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install -q --upgrade pip==26.3 setuptools==84.2.1 wheel==0.48.0
	$(PY) -m pip install -q -c requirements.lock -e '.[all]' --group test --group docs
	touch $@

# numba's on-disk cache of a function is keyed by its own file only, so a kernel would keep the
# stale inlined code of a helper edited in another module: drop every cache older than the newest
# source file it can inline from (the methods' and the model's kernels never inline the harness,
# so editing benchmarks/ keeps them; a fresh clone has none; after an edit numba recompiles)
numba-cache:
	@newest=$$(ls -t $$(find integrators problems -name '*.py') | head -1); \
	find integrators problems -name '*.nb[ic]' ! -newer "$$newest" -delete; \
	newest=$$(ls -t $$(find integrators problems benchmarks -name '*.py') | head -1); \
	find benchmarks -name '*.nb[ic]' ! -newer "$$newest" -delete

# compile every kernel once into numba's cache (a fresh checkout has none), in three processes
# side by side (the two halves of the registry and the batch kernels; they share the cores),
# again after a source file changed: the tests and a first run then pay no compiling
warm: $(WARM)

$(WARM): $(STAMP) $(shell find integrators problems benchmarks -name '*.py')
	$(MAKE) --no-print-directory numba-cache
	@s=0; $(PY) -m integrators.warm 1/2 & a=$$!; $(PY) -m integrators.warm 2/2 & b=$$!; \
	  $(PY) -m benchmarks.ensemble.warm & c=$$!; \
	  wait $$a || s=1; wait $$b || s=1; wait $$c || s=1; exit $$s
	touch $@

# the documentation site, into docs/_build/html; a warning (a broken link or reference) fails it
docs: setup
	$(PY) -m sphinx -W --keep-going -q -b html docs docs/_build/html

test: setup numba-cache warm
	$(PY) -m pytest --require-all --durations=15 -n $(JOBS)

# the slow tests: kills, Ctrl-C, subprocesses, a Dask cluster losing its workers, the README's
# and the docs' pages run as written (26 min on 2 cores in 2 processes)
test-slow: setup numba-cache warm
	$(PY) -m pytest --require-all --durations=25 -n $(JOBS) -m "slow and not study"

# the quick plan: reruns the quick steps whose inputs (code, package versions, settings, files
# read, the machine for timings) changed, reuses the others and keeps the files of the full
# steps; ~15 min on 2 cores when every quick step runs (docs/reproduce.md)
reproduce: setup numba-cache warm
	$(VENV)/bin/rsfbench reproduce --out results

# the full plan: also the quick work-precision study, the 2× speed target on every study problem
# and scipy's RK45 to its 600 s budget, the solver-effect and problem-family studies (about
# 3.5 h on 2 cores when every step runs; `rsfbench reproduce --full --dry-run` says what would)
reproduce-full: setup numba-cache warm
	$(VENV)/bin/rsfbench reproduce --full --out results

# the pytest-benchmark suite (benchmarks/test_*.py): timings at matched accuracy, as JSON
bench: setup numba-cache warm
	$(PY) -m pytest benchmarks --benchmark-json results/benchmarks.json \
	  --benchmark-columns=min,median,rounds --benchmark-sort=min

clean:
	rm -rf $(VENV) build *.egg-info
	find integrators problems benchmarks -name '*.nb[ic]' -delete
