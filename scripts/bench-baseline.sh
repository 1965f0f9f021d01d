#!/usr/bin/env bash
# The step benchmarks of this build beside a baseline build of an earlier commit, in one run.
#
#   scripts/bench-baseline.sh BUILD_DIR [BASELINE_COMMIT] [ROUNDS]
#
# The baseline is checked out as a git worktree in build-baseline/src and built in
# build-baseline/build with the same flags (once; later runs reuse it). The two benchmark
# binaries then run in turns, ROUNDS times each, so that a busy machine slows both alike; the
# table gives each benchmark's median wall time per iteration and the ratio baseline / current.
set -euo pipefail
cd "$(dirname "$0")/.."

build=${1:?usage: bench-baseline.sh BUILD_DIR [BASELINE_COMMIT] [ROUNDS]}
# 805c660: the last commit before the step work (model apart from state landed, exports unchanged).
baseline=${2:-805c660}
rounds=${3:-5}
# Benchmark filters, run one at a time (the CSV report needs one set of counters per run).
filters=${BENCH_FILTERS:-'BM_GelPhantom_CG25/ BM_GelPhantom_Cholmod/ BM_GelPhantomCoarse_CG25/ BM_PalpationReplay/'}
base_src=build-baseline/src
base_build=build-baseline/build

if ! git cat-file -e "$baseline^{commit}" 2>/dev/null; then
  echo "bench-baseline: commit $baseline is not in this clone (a shallow clone?); fetch it or pass another" >&2
  exit 2
fi
if [ ! -d "$base_src" ] || [ "$(git -C "$base_src" rev-parse HEAD 2>/dev/null)" != "$(git rev-parse "$baseline^{commit}")" ]; then
  rm -rf "$base_src"
  git worktree prune
  git worktree add --detach "$base_src" "$baseline" >/dev/null
fi
if [ ! -f "$base_build/build.ninja" ]; then
  launcher=()
  command -v ccache >/dev/null && launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache)
  cmake -S "$base_src" -B "$base_build" -G Ninja -DCMAKE_BUILD_TYPE=Release "${launcher[@]}" >/dev/null
fi
echo "Building the baseline ($baseline) in $base_build ..."
cmake --build "$base_build" -j "$(nproc)" --target viscera_bench | tail -1

# Scenes are read from each build's own source tree (VISCERA_SOURCE_DIR), so each binary runs
# the scenes of its commit; the replay benchmark's trajectory and scene are the same files.
results=$(mktemp)
trap 'rm -f "$results"' EXIT
for ((r = 1; r <= rounds; ++r)); do
  for filter in $filters; do
    for which in baseline current; do
      bin=$build/tests/viscera_bench
      [ "$which" = baseline ] && bin=$base_build/tests/viscera_bench
      echo "round $r/$rounds: $which $filter" >&2
      "$bin" --benchmark_filter="$filter" --benchmark_format=csv 2>/dev/null |
        awk -F, -v w="$which" '$1 ~ /^"BM_/ { gsub(/"/, "", $1); print w "," $1 "," $3 "," $5 }' >> "$results"
    done
  done
done

# Median of each benchmark's per-round times (real time, in the benchmark's unit).
awk -F, '
  { key = $2; unit[key] = $4; n[$1 SUBSEP key]++; t[$1 SUBSEP key SUBSEP n[$1 SUBSEP key]] = $3; keys[key] = 1 }
  function median(w, k,    m, i, j, a, tmp) {
    m = n[w SUBSEP k]; if (!m) return -1
    for (i = 1; i <= m; ++i) a[i] = t[w SUBSEP k SUBSEP i]
    for (i = 1; i <= m; ++i) for (j = i + 1; j <= m; ++j) if (a[j] < a[i]) { tmp = a[i]; a[i] = a[j]; a[j] = tmp }
    return m % 2 ? a[(m + 1) / 2] : (a[m / 2] + a[m / 2 + 1]) / 2
  }
  END {
    printf "%-58s %12s %12s %8s\n", "benchmark (median of rounds)", "baseline", "current", "speed-up"
    for (k in keys) {
      b = median("baseline", k); c = median("current", k)
      if (b < 0 || c < 0) { printf "%-58s %12s %12s %8s\n", k, b < 0 ? "-" : b, c < 0 ? "-" : c, "-"; continue }
      printf "%-58s %9.3f %-2s %9.3f %-2s %7.2fx\n", k, b, unit[k], c, unit[k], b / c
    }
  }' "$results" | { read -r header; echo "$header"; sort; }
