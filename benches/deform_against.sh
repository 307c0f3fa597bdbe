#!/usr/bin/env bash
# Every deform-terrain example, this checkout's search against an earlier revision's, in one
# run on this machine: the two release binaries take turns on each example (`ROUNDS` times,
# the fastest wall time kept, so a noisy neighbour hurts both alike) and the table gives
# each one's time, fitness, operations, evaluations and constraint figures side by side.
# The wall time is the whole `landform run` (start, terrain, constraints, search, every
# artifact written); the search time, the convergence alone, is the fastest the build logs
# (`search_ms`, logged since the speed work; "—" for a build that does not).
#
#   bash benches/deform_against.sh [REVISION]     (default 0099096, before the speed work)
#
# The earlier revision is built once into target/against-<rev> (a worktree under target/).
set -euo pipefail
cd "$(dirname "$0")/.."
rev=${1:-0099096}
rounds=${ROUNDS:-3}
old_dir=target/against-$rev
if [ ! -x "$old_dir/bin/landform" ]; then
    rm -rf "$old_dir/src"
    git worktree add --force --detach "$old_dir/src" "$rev" >/dev/null
    cargo build --release --bin landform --manifest-path "$old_dir/src/Cargo.toml" --target-dir "$old_dir/target"
    mkdir -p "$old_dir/bin"
    cp "$old_dir/target/release/landform" "$old_dir/bin/landform"
    git worktree remove --force "$old_dir/src"
fi
cargo build --release --bin landform
new=target/release/landform
old=$old_dir/bin/landform
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
mkdir -p "$work/deform-terrain"
printf '| example | build | wall (best of %s) | search | fitness | operations | evaluations | stopped | constraints |\n|---|---|---:|---:|---:|---:|---:|---|---|\n' "$rounds"
for example in api/deform-terrain/*.json; do
    name=$(basename "$example" .json)
    cp "$example" "$work/deform-terrain/$name.json"
    declare -A best=() search=()
    for _ in $(seq "$rounds"); do
        for which in old new; do
            bin=${!which}
            start=$(date +%s%N)
            RUST_LOG=landform=debug NO_COLOR=1 "$bin" run --out "$work/$which-$name" "$work/deform-terrain/$name.json" >"$work/log" 2>&1
            ms=$((($(date +%s%N) - start) / 1000000))
            if [ -z "${best[$which]:-}" ] || [ "$ms" -lt "${best[$which]}" ]; then best[$which]=$ms; fi
            searched=$(sed 's/\x1b\[[0-9;]*m//g' "$work/log" | grep -o 'search_ms=[0-9]*' | head -1 | cut -d= -f2 || true)
            if [ -n "$searched" ] && { [ -z "${search[$which]:-}" ] || [ "$searched" -lt "${search[$which]}" ]; }; then
                search[$which]=$searched
            fi
        done
    done
    for which in old new; do
        python3 - "$name" "$which" "${best[$which]}" "${search[$which]:-}" "$work/$which-$name/job.json" <<'PY'
import json, sys
name, which, ms, searched, path = sys.argv[1:]
r = json.load(open(path))["result"]
figures = []
for c in r["constraints"]:
    keep = {k: v for k, v in c.items() if k not in ("kind", "weight", "fitness") and isinstance(v, (int, float))}
    figures.append(c["kind"] + " " + ", ".join(f"{k} {v:.3g}" for k, v in keep.items()))
searched = f"{int(searched) / 1000:.2f} s" if searched else "—"
print(f"| {name} | {which} | {int(ms) / 1000:.2f} s | {searched} | {r['fitness']:.3e} | {r['operations']} | "
      f"{r['evaluations']} | {r['stopped']} | {'; '.join(figures)} |")
PY
    done
    unset best search
done
