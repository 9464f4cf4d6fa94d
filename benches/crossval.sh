#!/usr/bin/env bash
# Cross-validation benchmark (issue 6): full 6,561-capture simulated sessions (walkway, 64 × 64
# images, seed 11) compared against the simulator's Integra-like spectral reference (seed 5),
# as measured and with a −1 %/h gain correction. Prints the BENCHMARKS.md table rows.
# Run: bash benches/crossval.sh   (about 3 minutes)
set -euo pipefail
cd "$(dirname "$0")/.."
cargo build --release --quiet
W=$(mktemp -d)
trap 'rm -rf "$W"' EXIT
REPO=$(pwd)
scenario() { # name realism [fault lines]
  local name=$1 realism=$2; shift 2
  {
    echo "rig_config = \"$REPO/config/sim.toml\""
    echo '[session]'; echo "id = \"$name\""; echo "capture_root = \"$W/caps\""
    echo "port = \"$W/port\""; echo 'speed = 0'; echo 'seed = 11'
    echo '[material]'; echo 'preset = "walkway"'; echo "realism = \"$realism\""
    for f in "$@"; do echo '[[faults]]'; echo -e "$f"; done
  } > "$W/$name.toml"
}
scenario clean clean
scenario realistic realistic
scenario step realistic 'kind = "lamp-step"\nat_capture = 3280\nstep_pct = -3.0'
scenario decay realistic 'kind = "lamp-decay"\nat_capture = 0\nrate_pct_per_h = 1.0\nmodel = "exponential"'
scenario joint realistic 'kind = "joint-offset"\nat_capture = 3280\njoint = 2\noffset_deg = 2.0'
(cd sim && python3 -m goniosim reference "$W/clean.toml" --out "$W/ref.txt" --seed 5 >/dev/null)
echo "| session | table | compared | left out (reference uncertain) | ΔE*ab max / avg / median | ΔE00 max / avg / median | κ(T) | compare time |"
echo "|---|---|---|---|---|---|---|---|"
for n in clean realistic step decay joint; do
  (cd sim && exec python3 -m goniosim run "$W/$n.toml" --linger 30 >/dev/null 2>&1) &
  SIM=$!
  for _ in $(seq 200); do [ -e "$W/port" ] && break; sleep 0.1; done
  target/release/goniowatch run --config config/sim.toml --session "$W/s-$n" --port "$W/port" \
    --capture-root "$W/caps" --quiet > "$W/$n.log"
  kill "$SIM" 2>/dev/null || true; wait "$SIM" 2>/dev/null || true
  rm -f "$W/port"
  for extra in "" "--drift-rate=-1"; do
    start=$(date +%s.%N)
    target/release/goniowatch compare "$W/s-$n" "$W/ref.txt" --json $extra > "$W/c.json"
    secs=$(echo "$(date +%s.%N) - $start" | bc)
    python3 - "$n" "$extra" "$W/c.json" "$secs" <<'PY'
import json, sys
n, extra, path, secs = sys.argv[1:]
c = json.load(open(path))
rows = [("as measured", c["table3"])] if not extra else [(f"gain-corrected {c['gain_corrected'][0]['rate_pct_per_h']:+.1f} %/h", c["gain_corrected"][1])]
for name, t in rows:
    a, b = t["de76"], t["de2000"]
    print(f"| {n} | {name} | {c['captures_compared']} | {c['captures_reference_uncertain']} | {a['max']:.2f} / {a['avg']:.2f} / {a['median']:.2f} | {b['max']:.2f} / {b['avg']:.2f} / {b['median']:.2f} | {t['transform']['condition']:.0f} | {float(secs):.2f} s |")
PY
  done
  grep "occlusion substitutes" "$W/$n.log" | sed "s/^/    $n: /" >&2
done
