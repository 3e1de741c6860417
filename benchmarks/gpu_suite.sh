#!/usr/bin/env bash
# Every GPU measurement of ambulo in one run, for a GPU machine reached once.
#
#   OUT=/some/folder bash benchmarks/gpu_suite.sh      # from the repository root
#
# In order: the machine and versions; the figures (SUITE_PARTS "figures"): the cold start
# (import, env build and first step of humanoid-walk on CUDA with an empty Warp kernel cache:
# the kernel compile) and the warm start (the same in a second process, kernels from that
# cache); benchmarks/env_gpu.py, profile_gpu.py, render_gpu.py (when present); then every GPU
# test of the project (SUITE_PARTS "tests", with AMBULO_TEST_DEVICE=cuda); the CPU benchmarks
# env_cpu.py and engine_cpu.py, short (SUITE_CPU=1). Each part runs under `timeout` with its own
# budget, cut to what is left of the suite's (SUITE_BUDGET_S, 570 s: one device call of at most
# 10 minutes), so one failure or hang costs only its part; a part that would get under 20 s is
# skipped and says so. The figures (~230 s with the ~2.5 minute first compile) and every GPU
# test (~420 s) do not fit one call: run `SUITE_PARTS=figures` and `SUITE_PARTS=tests` as two.
#
# Writes four files (the device tool brings back at most 8): $OUT/suite.log (everything),
# $OUT/results.json ({part: {status, rc, seconds, result}}, result being the part's parsed
# `RESULT {json}` line; gpu_tests's is its summary), $OUT/gpu_tests.json (each GPU test's
# outcome and seconds) and $OUT/profile_trace.json.gz (the profiler's Chrome trace).
# Environment: PYTHON (default python3); SUITE_PARTS, SUITE_BUDGET_S and GPU_TESTS_S (the tests'
# budget) as above; SUITE_PYTEST_ARGS, more pytest arguments for the tests (e.g. --deselect); PYTHONPATH may hold mujoco, warp, mujoco_warp and
# other wheels (e.g. /tmp/site): src/ is put in front of it. SUITE_SMOKE=1 runs every part on
# Warp's CPU device with a few envs, to check the script itself on a machine without a GPU.
# The kernel cache stays in /tmp/ambulo-suite-warp-cache (emptied at the start) for later runs.
set -u

PY=${PYTHON:-python3}
OUT=${OUT:-/tmp/ambulo-gpu-suite}
BUDGET_S=${SUITE_BUDGET_S:-570}
PARTS_WANTED=${SUITE_PARTS:-figures tests}
in_parts() { [[ " $PARTS_WANTED " == *" $1 "* ]]; }
mkdir -p "$OUT"
LOG=$OUT/suite.log
: >"$LOG"
WORK=$(mktemp -d /tmp/ambulo-gpu-suite.XXXXXX)
if [ "${SUITE_SMOKE:-0}" = 1 ]; then
  DEV=cpu SIZES=4 PROFILE_N=4 STEPS=3 WARMUP=2 RENDER_N=4 CPU_N=16 START_N=4
  RENDER_SIZE=(--width 32 --height 24)
else
  DEV=cuda SIZES=1024,4096,16384 PROFILE_N=4096 STEPS=60 WARMUP=20 RENDER_N=1024 CPU_N=1024 START_N=4096
  RENDER_SIZE=()
fi
PARTS=$WORK/parts.jsonl
: >"$PARTS"
export PYTHONPATH="$PWD/src${PYTHONPATH:+:$PYTHONPATH}"
export PYTHONUNBUFFERED=1
# rsl-rl (tests/rl) imports GitPython, which refuses to import without a git executable unless told
export GIT_PYTHON_REFRESH=${GIT_PYTHON_REFRESH:-quiet}
# an empty kernel cache, so the first part measures a cold start; later parts reuse it
# (the smoke run keeps Warp's usual cache: a CPU compile of everything takes many minutes)
# (a tests-only run keeps it: what an earlier call on this machine compiled is reused)
if [ "${SUITE_SMOKE:-0}" != 1 ]; then
  export WARP_CACHE_PATH=/tmp/ambulo-suite-warp-cache
  in_parts figures && rm -rf "$WARP_CACHE_PATH"
  mkdir -p "$WARP_CACHE_PATH"
fi
START=$(date +%s)
DEADLINE=$((START + BUDGET_S))

say() { echo "$*" | tee -a "$LOG"; }

# part NAME BUDGET_S COMMAND...: run COMMAND under timeout, log its output, keep its RESULT line
part() {
  local name=$1 budget=$2
  shift 2
  local left=$((DEADLINE - $(date +%s)))
  local limit=$((budget < left ? budget : left))
  if ((limit < 20)); then
    say "== $name: skipped (${left} s left of the suite's ${BUDGET_S} s)"
    printf '{"name": "%s", "status": "skipped", "rc": null, "seconds": 0}\n' "$name" >>"$PARTS"
    return
  fi
  say "== $name (budget ${limit} s, at +$(($(date +%s) - START)) s): $*"
  local t0 rc status ms seconds
  t0=$(date +%s%N)
  timeout -k 10 "$limit" "$@" >"$WORK/$name.out" 2>&1
  rc=$?
  ms=$((($(date +%s%N) - t0) / 1000000))
  seconds=$(printf '%d.%d' $((ms / 1000)) $((ms % 1000 / 100)))
  cat "$WORK/$name.out" >>"$LOG"
  case $rc in
    0) status=ok ;;
    124 | 137) status=timeout ;;
    *) status=failed ;;
  esac
  say "== $name: $status (rc $rc) in ${seconds} s"
  local result
  result=$(grep '^RESULT ' "$WORK/$name.out" | tail -n 1 | cut -c8-)
  printf '{"name": "%s", "status": "%s", "rc": %d, "seconds": %s, "result": %s}\n' \
    "$name" "$status" "$rc" "$seconds" "${result:-null}" >>"$PARTS"
}

# the cold/warm start probe: seconds to import, build humanoid-walk and step it
cat >"$WORK/start_probe.py" <<'PY'
import json, os, sys, time
t0 = time.perf_counter()
import torch
import warp as wp
import ambulo.envs
kind, device, n = sys.argv[1], sys.argv[2], int(sys.argv[3])
sync = torch.cuda.synchronize if device.startswith("cuda") else (lambda: None)
import_s = time.perf_counter() - t0
t = time.perf_counter()
env = ambulo.envs.make("humanoid-walk", num_envs=n, device=device, engine="warp")
sync()
make_s = time.perf_counter() - t
actions = torch.zeros(env.num_envs, env.num_actions, device=env.device)
steps = []
for _ in range(3):
    t = time.perf_counter()
    env.step(actions)
    sync()
    steps.append(time.perf_counter() - t)
cache = wp.config.kernel_cache_dir
files = sum(len(f) for _, _, f in os.walk(cache))
print("RESULT " + json.dumps({
    "benchmark": "gpu_start", "kind": kind, "task": "humanoid-walk", "num_envs": n,
    "device": torch.cuda.get_device_name() if device.startswith("cuda") else "Warp CPU device",
    "import_s": round(import_s, 2), "make_s": round(make_s, 2),
    "first_step_s": round(steps[0], 3), "later_step_ms": round(1e3 * min(steps[1:]), 3),
    "to_first_step_s": round(time.perf_counter() - t0 - sum(steps[1:]), 2),
    "engine_compile_time_s": env.engine.compile_time_s, "warp_cache_dir": cache, "warp_cache_files": files}))
PY

COMMIT=$(git rev-parse --short HEAD 2>/dev/null || echo unknown)
say "ambulo GPU suite, $(date -u +%Y-%m-%dT%H:%M:%SZ), commit $COMMIT (+ working tree), budget ${BUDGET_S} s"
if command -v nvidia-smi >/dev/null; then nvidia-smi 2>&1 | tee -a "$LOG"; else say "(no nvidia-smi)"; fi
"$PY" - <<'PY' 2>&1 | tee -a "$LOG"
import importlib.metadata as md, platform
names = ["torch", "warp-lang", "mujoco", "mujoco-warp", "rsl-rl-lib", "tensordict", "numpy"]
def version(name):
    try:
        return md.version(name)
    except md.PackageNotFoundError:
        return "not installed"
print("python", platform.python_version(), "|", ", ".join(f"{n} {version(n)}" for n in names))
import torch
print("torch CUDA", torch.version.cuda, "| available:", torch.cuda.is_available(),
      "|", torch.cuda.get_device_name() if torch.cuda.is_available() else "no GPU")
PY

if in_parts figures; then
  part cold_start 180 "$PY" "$WORK/start_probe.py" cold "$DEV" "$START_N"
  part warm_start 30 "$PY" "$WORK/start_probe.py" warm "$DEV" "$START_N"
  part env_gpu 120 "$PY" benchmarks/env_gpu.py --device $DEV --num-envs $SIZES --steps $STEPS --warmup $WARMUP
  part profile_gpu 45 "$PY" benchmarks/profile_gpu.py --device $DEV --num-envs $PROFILE_N \
    --steps $((STEPS < 20 ? STEPS : 20)) --warmup $WARMUP --trace "$WORK/profile_trace.json"
  [ -f "$WORK/profile_trace.json" ] && gzip -c "$WORK/profile_trace.json" >"$OUT/profile_trace.json.gz"
  if [ -f benchmarks/render_gpu.py ]; then
    part render_gpu 70 "$PY" benchmarks/render_gpu.py --device $DEV --num-worlds $RENDER_N \
      ${RENDER_SIZE[@]+"${RENDER_SIZE[@]}"} --steps $((STEPS < 50 ? STEPS : 50)) --repeats 2
  fi
fi
# the tests come after the figures: other models' first runs compile more kernels.
# Every test that needs or uses CUDA (benchmarks/cuda_tests.py selects them: a skipif whose reason
# names CUDA, or a module that reads AMBULO_TEST_DEVICE), from the files that mention either;
# which ran, passed, failed, skipped or were not reached goes to $OUT/gpu_tests.json, rewritten
# after every test so a timeout still leaves it. Budget: tests/engine + the tiled camera took
# ~280 s on the H100 (2026-11-23: 19 tests in the 150 s they had, 6 not reached); perception's
# CUDA tests, tests/rl/test_sync_free_gpu.py and tests/sim/test_world_cuda.py were not timed
# on a GPU yet (estimated 140 s): 420 s. The JSON's per-test seconds size the next budget.
if in_parts tests; then
  mapfile -t TESTS < <(grep -rlE "AMBULO_TEST_DEVICE|cuda\.is_available" tests --include='test_*.py' | sort)
  # the smoke run only checks the selection (collect-only): the tests themselves take minutes on Warp's CPU
  TEST_MODE=()
  [ "${SUITE_SMOKE:-0}" = 1 ] && TEST_MODE=(--collect-only)
  [ ${#TESTS[@]} -gt 0 ] && part gpu_tests "${GPU_TESTS_S:-420}" env AMBULO_TEST_DEVICE=$DEV \
    PYTHONPATH="$PWD/benchmarks:$PYTHONPATH" "$PY" -m pytest -q -p no:cacheprovider -p cuda_tests \
    --cuda-report "$OUT/gpu_tests.json" --continue-on-collection-errors ${TEST_MODE[@]+"${TEST_MODE[@]}"} \
    ${SUITE_PYTEST_ARGS:-} "${TESTS[@]}"
fi
[ "${SUITE_CPU:-0}" = 1 ] && part env_cpu 35 "$PY" benchmarks/env_cpu.py --num-envs $CPU_N --steps $((STEPS < 40 ? STEPS : 40)) --repeats 1
[ "${SUITE_CPU:-0}" = 1 ] && part engine_cpu 20 "$PY" benchmarks/engine_cpu.py --num-worlds $CPU_N --steps $((STEPS < 100 ? STEPS : 100)) \
  --repeats 2

"$PY" - "$PARTS" "$OUT/results.json" "$WORK" <<'PY' 2>&1 | tee -a "$LOG"
import json, os, sys
parts = {}
for line in open(sys.argv[1]):
    try:
        row = json.loads(line)
    except json.JSONDecodeError as err:  # a RESULT line that is not JSON: keep the part, say so
        row = {"name": line.split('"')[3], "status": "bad RESULT line", "error": str(err)}
    name = row.pop("name")
    out = os.path.join(sys.argv[3], f"{name}.out")
    if os.path.exists(out):  # e.g. pytest's summary, or the error that ended the part
        row["last_line"] = ([l.strip() for l in open(out, errors="replace") if l.strip()] or [""])[-1][:300]
    parts[name] = row
tests = os.path.join(os.path.dirname(sys.argv[2]), "gpu_tests.json")
if "gpu_tests" in parts and os.path.exists(tests):
    report = json.load(open(tests))
    parts["gpu_tests"]["result"] = {k: report[k] for k in ("device", "test_device", "selected", "summary")}
json.dump(parts, open(sys.argv[2], "w"), indent=1)
print(f"{'part':<12} {'status':<9} {'s':>6}  headline")
for name, row in parts.items():
    r = row.get("result") or {}
    head = {k: r[k] for k in ("ratio", "to_first_step_s", "make_s", "first_step_s", "wall_ms_per_step",
                              "device_busy_fraction", "target", "summary") if k in r}
    head = json.dumps(head) if head else row.get("last_line", "")[:100]
    print(f"{name:<12} {row['status']:<9} {row.get('seconds') or 0:>6.1f}  {head}")
PY
say "suite done in $(($(date +%s) - START)) s; files in $OUT: $(ls "$OUT" | tr '\n' ' ')"
rm -rf "$WORK"
