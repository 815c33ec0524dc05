# The two commands the README opens with. Each runs scripts/setup first (idempotent, ~1 s when done).
.PHONY: setup demo test lint rust-test validation bench

CARGO ?= cargo
PY := deps/venv/bin/python

setup:
	@scripts/setup

## Runs the whole pipeline on the bundled default scene (data-fixtures/demo) into runs/demo/.
demo: setup
	$(CARGO) build --release -p pipeline
	target/release/pipeline run configs/demo.toml

## Builds and runs every Rust test and the Python validation suite; non-zero exit on any failure.
test: setup lint rust-test validation

lint:
	$(CARGO) fmt --all --check
	$(CARGO) clippy --workspace --all-targets --locked -- -D warnings

rust-test:
	$(CARGO) test --workspace --locked

# The validation suite runs our example binaries, which `cargo test` has built into target/debug/examples.
validation:
	$(PY) -m pytest tests/validation -q -rs

bench: setup
	$(CARGO) bench --workspace
