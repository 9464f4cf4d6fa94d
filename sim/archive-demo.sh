#!/usr/bin/env bash
# A finished capture set checked end to end: the simulator writes the archive scenario's 6,561
# captures with Bonn-style names (tl015_pl060_tv030_pv000.hdr; a lamp decay and a dark frame in
# it) without any serial link, then `goniowatch check` reads the folder, places every file on the
# plan by its name and checks the set; then the BRDF and the table are exported and the report
# written. Run from anywhere.
set -euo pipefail
cd "$(dirname "$0")/.."

python3 -m pip install --quiet --disable-pip-version-check --root-user-action=ignore -r sim/requirements.txt
cargo build --release --quiet

ROOT=target/sim-archive
rm -rf "$ROOT"
(cd sim && python3 -m goniosim archive scenarios/archive.toml --out "../$ROOT" --naming bonn)
target/release/goniowatch check "$ROOT/archive" --config config/sim.toml --session "$ROOT/archive.check"
# What a lab takes away: the BRDF on MERL's grid (drift divided out, with a sidecar saying how far
# to trust it), every capture raw and corrected, and the report with its BRDF plots
target/release/goniowatch export "$ROOT/archive.check" --format merl
target/release/goniowatch export "$ROOT/archive.check" --format table
target/release/goniowatch report "$ROOT/archive.check"
