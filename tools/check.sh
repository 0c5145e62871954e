#!/usr/bin/env bash
# Every check of the project, in one command (house style 14): formatting, lints, type stubs,
# the Rust and Python test suites, and every example. Run after `pip install -e ".[test]"`.
set -euo pipefail
cd "$(dirname "$0")/.."

echo "== rustfmt"
cargo fmt --all -- --check
echo "== import cycles of the core"
python tools/check_imports.py
echo "== clippy"
cargo clippy --workspace --all-targets --release -- -D warnings
echo "== ruff"
ruff check python tests benchmarks examples
ruff format --check python tests benchmarks examples
echo "== Rust tests"
cargo test --release -p flexmbd-core
echo "== Python tests (including the stub check)"
python -m pytest -q
echo "== examples"
for example in examples/*.py; do
    echo "-- $example"
    python "$example"
done
echo "all checks passed"
