# The two commands the README opens with. Each runs scripts/setup first (idempotent, ~1 s when done).
.PHONY: setup demo test lint rust-test isa-test reliability-test validation bench fuzz

CARGO ?= cargo
PY := deps/venv/bin/python

setup:
	@scripts/setup

## Runs the whole pipeline on the bundled default scene (data-fixtures/demo) into runs/demo/.
demo: setup
	$(CARGO) build --release -p pipeline
	target/release/pipeline run configs/demo.toml

## Builds and runs every Rust test (natively, then the tracer's and the end-to-end tests again under Embree's
## SSE4.2, AVX and AVX2 kernels), the CI-sized kill and corruption runs, and the Python validation suite;
## non-zero exit on any failure.
test: setup lint rust-test isa-test reliability-test validation

lint:
	$(CARGO) fmt --all --check
	$(CARGO) clippy --workspace --all-targets --locked -- -D warnings

rust-test:
	$(CARGO) test --workspace --locked

# Embree rounds hits differently per instruction set: the tests must hold under every one (scripts/test-isa).
isa-test: rust-test
	scripts/test-isa

# Kill anywhere and corrupt anything, CI-sized (scripts/reliability; the full runs and their figures are in
# docs/reliability.md): a tiny run of the demo scan killed at 5 random moments, and 6 of its files damaged.
reliability-test: rust-test
	scripts/reliability kill --config tests/reliability/tiny.toml --bin target/debug/pipeline --kills 5 --seed 1
	scripts/reliability corrupt --config tests/reliability/tiny.toml --bin target/debug/pipeline --limit 6 --seed 1

# The validation suite runs our example binaries, which `cargo test` has built into target/debug/examples.
validation:
	$(PY) -m pytest tests/validation -q -rs

bench: setup
	$(CARGO) bench --workspace

## Every ingest reader against 10^6 mutated inputs each (release; ~5 min on 2 cores); CASES=N to change.
fuzz:
	scripts/fuzz $(or $(CASES),1000000)

# The realistic evaluation corpus (docs/realistic/README.md): every named scene built into CORPUS_DIR, outside
# git. Renders on one thread by default (CORPUS_THREADS); `house` takes the longest. A scene already built from
# the same XML and settings is kept (`scripts/corpus build --force` rebuilds one).
CORPUS_DIR ?= $(HOME)/.cache/ipt/corpus
CORPUS_SCENES ?= room-textured room-two-lights room-daylight modern-hall house
CORPUS_THREADS ?= 1
.PHONY: corpus
corpus:
	@for s in $(CORPUS_SCENES); do \
	  echo "corpus: $$s -> $(CORPUS_DIR)/$$s"; \
	  scripts/corpus build $$s $(CORPUS_DIR)/$$s --threads $(CORPUS_THREADS) || exit 1; \
	done

# The quality presets on the built corpus (`lab bench realistic`, release build): the whole pipeline per scene
# and preset, scored; runs kept under CORPUS_DIR/bench-runs and read back when rerun; tables and plot into
# docs/realistic/bench/. A scene not yet built is named in a one-line error (`make corpus` builds it).
BENCH_SCENES ?= room-textured,room-two-lights,room-daylight,modern-hall
.PHONY: bench-realistic
bench-realistic: setup
	$(CARGO) build --release -p lab -p pipeline
	target/release/lab bench realistic --corpus $(CORPUS_DIR) --scenes $(BENCH_SCENES) --out docs/realistic/bench
