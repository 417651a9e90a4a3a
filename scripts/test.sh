#!/usr/bin/env bash
# Every check: installs what the tests need, then format, lints and every test.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
# One full build: incremental caches would double target/'s size on disk
# (about 7 GB instead of 3 GB) and a one-shot build gains nothing from them.
# A developer's own `cargo test -p CRATE` keeps them.
export CARGO_INCREMENTAL="${CARGO_INCREMENTAL:-0}"
avail_kb=$(df -Pk . | awk 'NR == 2 { print $4 }')
if [ -n "$avail_kb" ] && [ "$avail_kb" -lt 5000000 ]; then
    echo "warning: $((avail_kb / 1024)) MiB free on this disk; the full test build needs about 4 GB" >&2
fi
rustup component add rustfmt clippy >/dev/null 2>&1 || true
echo "== format and lints"
cargo fmt --all -- --check
cargo clippy --workspace --all-targets -- -D warnings
# The API documentation builds without a broken link.
RUSTDOCFLAGS="-D warnings" cargo doc --workspace --no-deps --quiet
echo "== tests"
cargo test --workspace
