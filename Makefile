# The two commands the README opens with. Each runs scripts/setup first (idempotent, ~1 s when done).
.PHONY: setup demo test lint rust-test isa-test validation bench

CARGO ?= cargo
PY := deps/venv/bin/python

setup:
	@scripts/setup

## Runs the whole pipeline on the bundled default scene (data-fixtures/demo) into runs/demo/.
demo: setup
	$(CARGO) build --release -p pipeline
	target/release/pipeline run configs/demo.toml

## Builds and runs every Rust test (natively, then the tracer's and the end-to-end tests again under Embree's
## SSE4.2, AVX and AVX2 kernels) and the Python validation suite; non-zero exit on any failure.
test: setup lint rust-test isa-test validation

lint:
	$(CARGO) fmt --all --check
	$(CARGO) clippy --workspace --all-targets --locked -- -D warnings

rust-test:
	$(CARGO) test --workspace --locked

# Embree rounds hits differently per instruction set: the tests must hold under every one (scripts/test-isa).
isa-test: rust-test
	scripts/test-isa

# The validation suite runs our example binaries, which `cargo test` has built into target/debug/examples.
validation:
	$(PY) -m pytest tests/validation -q -rs

bench: setup
	$(CARGO) bench --workspace

# The realistic evaluation corpus (docs/realistic/README.md): every named scene built into CORPUS_DIR, outside
# git. Renders on one thread by default (CORPUS_THREADS); `house` takes the longest.
CORPUS_DIR ?= $(HOME)/.cache/ipt/corpus
CORPUS_SCENES ?= room-textured room-two-lights room-daylight modern-hall house
CORPUS_THREADS ?= 1
.PHONY: corpus
corpus:
	@for s in $(CORPUS_SCENES); do \
	  echo "corpus: $$s -> $(CORPUS_DIR)/$$s"; \
	  scripts/corpus build $$s $(CORPUS_DIR)/$$s --threads $(CORPUS_THREADS) || exit 1; \
	done
