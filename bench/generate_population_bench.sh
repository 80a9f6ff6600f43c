#!/usr/bin/env bash
# Speed of `generate --population` (issue 36: ≥ 10 bodies/s end to end on 2 cores), as a RATIO of
# two builds run alternately in one script, so the load of a shared machine hits both alike:
# OLD and NEW each make the same crowd (200 bodies, seed 3, the command of docs/population.md)
# ROUNDS times, in alternating order. Prints every run's wall and CPU seconds and bodies/s end to
# end, the median wall ratio and the total CPU ratio old / new, `uptime` before and after, and
# whether the two builds made the same crowd: the summary lines (met, flipped, diversity,
# self-intersections, roughness, KS), labels.csv cell by cell, and the largest vertex difference
# over every body (mm).
# Usage: bench/generate_population_bench.sh OLD_EXE NEW_EXE MODEL.npz [ROUNDS] [JOBS] [WORKDIR]
#   MODEL.npz: `bodymodel build` of docs/population.md's pop200 (built by NEW, so that it holds
#   the training subjects' diversity; OLD decodes them on every run). JOBS: generate --jobs
#   (default 0 = all cores). WORKDIR: default a temporary folder, removed at the end.
# Needs $BODYMODEL_DATA/anthropometry/nhanes_2017_2020_bmx_demo.csv.
set -euo pipefail
old="$(realpath "$1")"; new="$(realpath "$2")"; model="$(realpath "$3")"
rounds="${4:-3}"; jobs="${5:-0}"
work="${6:-$(mktemp -d "${TMPDIR:-/tmp}/bodymodel_genbench.XXXXXX")}"
[ -n "${6:-}" ] || trap 'rm -rf "$work"' EXIT
mkdir -p "$work"
people="${BODYMODEL_DATA:?set BODYMODEL_DATA}/anthropometry/nhanes_2017_2020_bmx_demo.csv"
count=200

run() {  # run NAME EXE ROUND: one crowd, its times appended to $work/times.txt
  local name="$1" exe="$2" r="$3" out="$work/$1-$3"
  rm -rf "$out"
  /usr/bin/time -f "%e %U %S" -o "$work/$name-$r.time" \
    "$exe" generate "$model" --population "$people" --count "$count" --seed 3 --jobs "$jobs" --out "$out" \
    >"$work/$name-$r.log" 2>"$work/$name-$r.err" || true
  read -r wall user sys <"$work/$name-$r.time"
  local speed
  speed=$(sed -n 's/^speed *\([0-9.]*\) bodies.*/\1/p' "$work/$name-$r.log")
  echo "$name $r $wall $user $sys $speed" >>"$work/times.txt"
  printf "| %s | %d | %.1f | %.1f | %.2f | %s |\n" "$name" "$r" "$wall" "$(echo "$user + $sys" | bc)" \
    "$(echo "$count / $wall" | bc -l)" "$speed"
}

echo "uptime before: $(uptime)"
: >"$work/times.txt"
printf "| build | round | wall s | CPU s | bodies/s end to end | the verb's loop bodies/s |\n|---|---:|---:|---:|---:|---:|\n"
for r in $(seq 1 "$rounds"); do
  if [ $((r % 2)) -eq 1 ]; then run old "$old" "$r"; run new "$new" "$r"; else run new "$new" "$r"; run old "$old" "$r"; fi
done
echo "uptime after:  $(uptime)"
python3 - "$work" "$rounds" "$count" <<'EOF'
import statistics, sys, os
work, rounds, count = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
t = {}
for line in open(os.path.join(work, "times.txt")):
    name, r, wall, user, sys_, *_ = line.split()
    t[(name, int(r))] = (float(wall), float(user) + float(sys_))
ratios = [t[("old", r)][0] / t[("new", r)][0] for r in range(1, rounds + 1)]
cpu_old = sum(t[("old", r)][1] for r in range(1, rounds + 1))
cpu_new = sum(t[("new", r)][1] for r in range(1, rounds + 1))
print(f"wall ratio old/new per round: {', '.join(f'{x:.3f}' for x in ratios)}; median {statistics.median(ratios):.3f}")
print(f"CPU ratio old/new (all rounds): {cpu_old / cpu_new:.3f} ({cpu_old:.1f} / {cpu_new:.1f} CPU-s)")
print(f"median bodies/s end to end: old {count / statistics.median(t[('old', r)][0] for r in range(1, rounds + 1)):.2f}, "
      f"new {count / statistics.median(t[('new', r)][0] for r in range(1, rounds + 1)):.2f}")

def summary(path):  # the crowd's figures, without the timing lines
    keep = []
    for line in open(path):
        if line.startswith("speed"):
            continue
        keep.append(line.rstrip("\n"))
    return keep
a, b = summary(os.path.join(work, f"old-{rounds}.log")), summary(os.path.join(work, f"new-{rounds}.log"))
print("summary lines identical" if a == b else "summary lines DIFFER:\n  " + "\n  ".join(
    f"old: {x}\n  new: {y}" for x, y in zip(a, b) if x != y))
la = open(os.path.join(work, f"old-{rounds}", "labels.csv")).read().splitlines()
lb = open(os.path.join(work, f"new-{rounds}", "labels.csv")).read().splitlines()
cells = sum(x != y for ra, rb in zip(la, lb) for x, y in zip(ra.split(","), rb.split(",")))
print(f"labels.csv: {len(la) - 1} / {len(lb) - 1} rows, {cells} cells differ")

def vertices(path):
    return [tuple(map(float, l.split()[1:4])) for l in open(path) if l.startswith("v ")]
worst = 0.0
for i in range(count):
    f = f"body_{i:03d}.obj"
    va, vb = vertices(os.path.join(work, f"old-{rounds}", f)), vertices(os.path.join(work, f"new-{rounds}", f))
    assert len(va) == len(vb), f
    worst = max(worst, max(max(abs(p - q) for p, q in zip(u, v)) for u, v in zip(va, vb)))
print(f"largest vertex difference over the {count} bodies: {worst:.3g} mm (as written in the OBJ files)")
EOF
