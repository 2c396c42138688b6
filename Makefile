# The two-command quickstart: `make demo` and `make test`. Every target that
# needs Python depends on the venv and on a release build of the extension,
# so a fresh clone needs nothing but Rust and Python 3.10+.

PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
PY := $(BIN)/python
# maturin develop installs into the environment named by VIRTUAL_ENV.
export VIRTUAL_ENV := $(abspath $(VENV))

RUST_SOURCES := $(shell find rust -name '*.rs' -o -name Cargo.toml) Cargo.toml
BUILT := $(VENV)/.built-release

.DEFAULT_GOAL := help

.PHONY: help
help: ## list the targets
	@grep -E '^[a-z-]+:.*## ' $(MAKEFILE_LIST) | awk -F':.*## ' '{printf "  %-8s %s\n", $$1, $$2}'

# A real file target: a missing or broken venv is rebuilt.
$(PY):
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip

$(VENV)/.deps: | $(PY)
	$(PY) -m pip install --quiet "maturin>=1.7,<2" "ruff>=0.6" "mypy>=1.10"
	touch $@

$(BUILT): $(VENV)/.deps $(RUST_SOURCES) pyproject.toml
	# -E test installs the runtime and test dependencies named in pyproject.toml.
	$(BIN)/maturin develop --release --quiet -E test
	touch $@

.PHONY: build
build: $(BUILT) ## build the extension (release) into .venv

.PHONY: demo
demo: $(BUILT) ## run the main job on the built-in sample; results under out/
	$(BIN)/imgform demo --out out --overwrite

.PHONY: test
test: $(BUILT) ## cargo test (core) and pytest
	cargo test --quiet
	$(PY) -m pytest -q

.PHONY: test-slow
test-slow: $(BUILT) ## the slow tests too
	$(PY) -m pytest -q -m "slow or not slow"

# Peers only the benchmarks use. eari-demosaic declares opencv-python, which would
# clash with the opencv-python-headless of the test extra (both provide cv2), so it
# is installed without its dependencies (numpy, scipy and cv2 are already there).
$(VENV)/.bench-peers: | $(PY)
	$(PY) -m pip install --quiet --no-deps eari-demosaic==0.1.4
	touch $@

.PHONY: bench-peers
bench-peers: $(VENV)/.bench-peers ## install the benchmark-only peers into .venv

.PHONY: bench
bench: $(BUILT) $(VENV)/.bench-peers ## side-by-side benchmarks against the peers
	@for b in $(filter-out benchmarks/summary.py,$(wildcard benchmarks/*.py)); do \
		echo "== $$b"; $(PY) $$b || exit 1; done
	# The README's short table follows the records just written.
	$(PY) benchmarks/summary.py --write

.PHONY: filters
filters: $(BUILT) ## rebuild the leung2011 demosaicer's least-squares filters
	$(PY) -m imgform_rs.training.leung2011

WEIGHTS := $(addprefix rust/imgform-core/src/demosaic/,raisr_weights.bin raisr_fast_weights.bin \
	raisr_cd_weights.bin fusion_weights.bin fusion_refined_weights.bin fusion_cnn_weights.bin)
# include_bytes! makes the weights part of the extension.
$(BUILT): $(WEIGHTS)

# The first 33 training photographs of the learned demosaicers (licences in
# python/imgform_rs/training/photos.py), at pinned versions: the training
# checks each file's SHA-256.
TRAINING_DATA := out/training-data
$(TRAINING_DATA)/.fetched: | $(PY)
	mkdir -p $(TRAINING_DATA)
	cd $(TRAINING_DATA) && apt-get download plasma-workspace-wallpapers=4:5.27.5-2 \
		lomiri-wallpapers-16.04=20.04.0-2 mate-backgrounds=1.26.0-1
	dpkg -x $(TRAINING_DATA)/plasma-workspace-wallpapers_*.deb $(TRAINING_DATA)/plasma
	dpkg -x $(TRAINING_DATA)/lomiri-wallpapers-16.04_*.deb $(TRAINING_DATA)/lomiri
	dpkg -x $(TRAINING_DATA)/mate-backgrounds_*.deb $(TRAINING_DATA)/mate
	$(PY) -m pip download --quiet --no-deps --only-binary=:all: --dest $(TRAINING_DATA) \
		scikit-learn==1.9.1 matplotlib==3.11.2
	touch $@

# The extended set (python/imgform_rs/training/catalogue.py, licences there): 266
# more photographs from five Debian packages, at pinned versions.
$(TRAINING_DATA)/.fetched-extended: $(TRAINING_DATA)/.fetched
	cd $(TRAINING_DATA) && apt-get download gcompris-qt-data=3.1-2 kphotoalbum=5.9.1-1 \
		tuxpaint-data=1:0.9.28-sdl2-1 palapeli-data=4:22.12.3-1 \
		lomiri-wallpapers-20.04=20.04.0-2
	dpkg -x $(TRAINING_DATA)/gcompris-qt-data_*.deb $(TRAINING_DATA)/gcompris
	dpkg -x $(TRAINING_DATA)/kphotoalbum_*.deb $(TRAINING_DATA)/kphotoalbum
	dpkg -x $(TRAINING_DATA)/tuxpaint-data_*.deb $(TRAINING_DATA)/tuxpaint
	dpkg -x $(TRAINING_DATA)/palapeli-data_*.deb $(TRAINING_DATA)/palapeli
	dpkg -x $(TRAINING_DATA)/lomiri-wallpapers-20.04_*.deb $(TRAINING_DATA)/lomiri-20.04
	touch $@

.PHONY: training-data
training-data: $(TRAINING_DATA)/.fetched-extended ## fetch the training photographs (Debian + PyPI)

.PHONY: weights
weights: $(BUILT) $(TRAINING_DATA)/.fetched-extended ## retrain the learned demosaicers ("raisr", "raisr_fast", "raisr_cd", "fusion", "fusion_refined", "fusion_cnn") and check the shipped weights bit for bit
	mkdir -p out
	# fusion_refined trains over the built extension's fusion, so it comes last.
	for m in raisr raisr_fast raisr_cd fusion fusion_refined; do \
		$(PY) -m imgform_rs.training.demosaic --method $$m --out out/$${m}_weights.bin && \
		cmp out/$${m}_weights.bin rust/imgform-core/src/demosaic/$${m}_weights.bin && \
		echo "$$m weights reproduced bit for bit" || exit 1; \
	done
	# fusion_cnn's network trains over fusion_refined, with PyTorch (41 minutes
	# on one core with AMX, ~7 GB of memory).
	$(PY) -m pip install --quiet "torch==2.15.0"
	$(PY) -m imgform_rs.training.cnn --out out/fusion_cnn_weights.bin
	cmp out/fusion_cnn_weights.bin rust/imgform-core/src/demosaic/fusion_cnn_weights.bin
	@echo "fusion_cnn weights reproduced bit for bit"

# The docs extra (Sphinx and friends, named in pyproject.toml) on top of the
# release build; maturin reinstalls the built extension with the extras, so
# cargo has nothing to rebuild.
$(VENV)/.docs-deps: $(BUILT)
	$(BIN)/maturin develop --release --quiet -E test,docs
	touch $@

.PHONY: docs
docs: $(VENV)/.docs-deps ## the documentation site into docs/_build/html, warnings as errors
	# -E: every page is read afresh, so the API pages follow the docstrings;
	# the gallery reruns every example, so the figures follow the code.
	$(PY) -m sphinx -E -W --keep-going -b html docs docs/_build/html
	@echo "open docs/_build/html/index.html"

.PHONY: lint
lint: $(VENV)/.deps ## cargo fmt, clippy -D warnings, ruff, stubtest
	cargo fmt --all -- --check
	cargo clippy --workspace --all-targets -- -D warnings
	$(BIN)/ruff check python tests benchmarks docs
	$(BIN)/ruff format --check python tests benchmarks docs
	$(MAKE) --no-print-directory $(BUILT)
	$(PY) -m mypy.stubtest imgform_rs._native --allowlist .mypy-stubtest-allowlist

.PHONY: clean
clean: ## remove build products and the venv
	rm -rf target $(VENV) out python/imgform_rs/*.so
	rm -rf docs/_build docs/generated docs/auto_examples docs/_generated docs/sg_execution_times.rst
