#!/bin/bash
# rounds_cgal.sh N MESHVET DIR: N rounds of CGAL's query on the one ASCII PLY in DIR
# (cgal_query.py), then MESHVET's one-thread scan of DIR right after CGAL's process and again.
# Prints each round (CGAL seconds, meshvet wall seconds twice) and the ratios of the medians.
# DIR must hold a real copy of the mesh: the scan does not follow symbolic links.
set -eu
N=$1; BIN=$2; DIR=$3
PY=${PY:-python3}
here=$(cd "$(dirname "$0")" && pwd)
mesh=$(find "$DIR" -maxdepth 1 -name '*.ply' | head -1)
out=$(mktemp)
scan() { { /usr/bin/time -f %e "$BIN" scan "$DIR" --jobs 1 --csv /dev/null -q; } 2>&1 | tail -1; }
for _ in $(seq "$N"); do
    c=$("$PY" "$here/cgal_query.py" "$mesh" | cut -d' ' -f1)
    a=$(scan); b=$(scan)
    echo "$c $a $b" | tee -a "$out"
done
python3 - "$out" <<'P'
import statistics as st, sys
rows = [list(map(float, line.split())) for line in open(sys.argv[1])]
c, a, b = (st.median(r[k] for r in rows) for k in range(3))
print(f"medians: CGAL {c:.3f} s; meshvet right after it {a:.3f} s ({c / a:.2f}x), next {b:.3f} s ({c / b:.2f}x)")
P
rm -f "$out"
