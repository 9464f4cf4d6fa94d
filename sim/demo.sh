#!/usr/bin/env bash
# The README's main job: set up, start the simulated rig on the default scenario, and run the
# goniowatch daemon beside it with progress, alarms and the summary. Run from anywhere.
set -euo pipefail
cd "$(dirname "$0")/.."

python3 -m pip install --quiet --disable-pip-version-check --root-user-action=ignore -r sim/requirements.txt
cargo build --release --quiet

SESSION="${SESSION:-target/demo-session}"
PORT=/tmp/goniowatch-rig
rm -rf "$SESSION" target/sim-captures/demo
(cd sim && exec python3 -m goniosim run scenarios/demo.toml --port "$PORT" --linger 60) &
SIM=$!
trap 'kill "$SIM" 2>/dev/null || true' EXIT
for _ in $(seq 100); do [ -e "$PORT" ] && break; sleep 0.1; done

target/release/goniowatch run --config config/sim.toml --session "$SESSION" --port "$PORT"
