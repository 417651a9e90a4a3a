#!/usr/bin/env bash
# The main job on the embedded default scene: installs what it needs, builds,
# runs `smartagg demo` (extra arguments are passed on; default --out demo-out).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
if [ $# -eq 0 ]; then set -- --out demo-out; fi
cargo run --release -p smartagg -- demo "$@"
