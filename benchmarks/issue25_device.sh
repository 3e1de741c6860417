#!/usr/bin/env bash
# Issue 25's GPU checks in one device call of ~8 minutes, results under the folder given as $1.
#
#   bash benchmarks/issue25_device.sh "$OUT"          # from the repository root, on the GPU machine
#
# Needs the GPU stack staged first (/work/shared/device/stage-gpu.sh, with
# EXTRA="rsl-rl-lib==5.5.1 tensordict==0.15.3 pyvers GitPython gitdb smmap": rsl-rl-lib and what
# it imports are not on the device image), then PYTHONPATH=/tmp/site. A preflight says which
# import is missing before anything runs. In order, each under `timeout` with its own budget cut
# to what is left of ISSUE25_BUDGET_S (470 s; a part that would get under 20 s is skipped):
#
#   1. tests/rl/test_sync_free_gpu.py: a PPO iteration of humanoid-walk on CUDA under torch's
#      sync debug mode (warn, then error) outside the update; it also compiles humanoid-walk's
#      kernels (~2.5 min with an empty cache) for the parts after it;
#   2. benchmarks/env_gpu.py at 4096 worlds: training's rollout step (the runner `ambulo train`
#      builds, rsl-rl's actor with the sync-free head) against raw MuJoCo Warp, and syncs/step;
#   3. benchmarks/profile_gpu.py at 4096 worlds: sync calls, device-to-host copies and torch's
#      sync warnings per step, from the profiler;
#   4. benchmarks/gpu_suite.sh SUITE_PARTS=tests: every other GPU test, with what is left
#      (the JSON lists the tests not reached).
#
# ISSUE25_SMOKE=1 runs it all on Warp's CPU device with 4 worlds (the CUDA tests skip, the suite
# only collects), to check the script on a machine without a GPU (tests/test_benchmarks_gpu_smoke.py).
#
# Writes 8 files (what the device tool brings back): summary.json (the headline of each part),
# sync_test.json, sync_test.log, env_gpu.log, profile_gpu.log, suite/suite.log,
# suite/results.json, suite/gpu_tests.json.
set -u
OUT=${1:?usage: bash benchmarks/issue25_device.sh OUT_FOLDER}
PY=${PYTHON:-python3}
BUDGET_S=${ISSUE25_BUDGET_S:-470}
mkdir -p "$OUT"
export PYTHONPATH="$PWD/src:$PWD/benchmarks${PYTHONPATH:+:$PYTHONPATH}"
export PYTHONUNBUFFERED=1 MUJOCO_GL=${MUJOCO_GL:-egl}
# rsl-rl imports GitPython, which refuses to import without a git executable unless told
export GIT_PYTHON_REFRESH=${GIT_PYTHON_REFRESH:-quiet}
# one kernel cache for every part (the suite keeps it in a tests-only run)
if [ "${ISSUE25_SMOKE:-0}" = 1 ]; then
  DEV=(--device cpu) N=4 STEPS=(--steps 3 --warmup 2) PSTEPS=(--steps 3 --warmup 2) CUDA_CHECK=
else
  DEV=() N=4096 STEPS=(--steps 60 --warmup 20) PSTEPS=(--steps 20 --warmup 20) CUDA_CHECK="assert torch.cuda.is_available(), 'torch sees no CUDA device'"
  export WARP_CACHE_PATH=/tmp/ambulo-suite-warp-cache
  mkdir -p "$WARP_CACHE_PATH"
fi
START=$(date +%s)
DEADLINE=$((START + BUDGET_S))
STATUS=$OUT/.status
: >"$STATUS"

# step NAME BUDGET_S LOG COMMAND...: COMMAND under timeout, its output in LOG, its status kept
step() {
  local name=$1 budget=$2 log=$3
  shift 3
  local left=$((DEADLINE - $(date +%s)))
  [ "${ISSUE25_SMOKE:-0}" = 1 ] && budget=$left  # Warp's CPU device: no part's budget holds there
  local limit=$((budget < left ? budget : left))
  if ((limit < 20)); then
    echo "== $name: skipped (${left} s left of ${BUDGET_S} s)" | tee -a "$log"
    echo "$name skipped null 0" >>"$STATUS"
    return
  fi
  echo "== $name (budget ${limit} s, at +$(($(date +%s) - START)) s): $*"
  local t0=$(date +%s) rc
  timeout -k 10 "$limit" "$@" >"$log" 2>&1
  rc=$?
  local status=ok
  case $rc in 0) ;; 124 | 137) status=timeout ;; *) status=failed ;; esac
  echo "== $name: $status (rc $rc) in $(($(date +%s) - t0)) s"
  tail -n 5 "$log"
  echo "$name $status $rc $(($(date +%s) - t0))" >>"$STATUS"
}

if ! "$PY" -c "import torch, warp, mujoco, mujoco_warp, rsl_rl, tensordict, git
$CUDA_CHECK
print('torch', torch.__version__, '| warp', warp.__version__, '| mujoco', mujoco.__version__, \
'| rsl-rl', __import__('importlib.metadata').metadata.version('rsl-rl-lib'), '|', torch.cuda.get_device_name() if torch.cuda.is_available() else 'no CUDA')" \
  >"$OUT/sync_test.log" 2>&1; then
  cat "$OUT/sync_test.log"
  echo "preflight failed: stage the GPU stack with EXTRA=\"rsl-rl-lib==5.5.1 tensordict==0.15.3 pyvers GitPython gitdb smmap\"" \
    "and set PYTHONPATH=/tmp/site" | tee -a "$OUT/sync_test.log"
  exit 3
fi
cat "$OUT/sync_test.log"

step sync_test 240 "$OUT/sync_test.log" "$PY" -m pytest -q -rA -p no:cacheprovider -p cuda_tests \
  --cuda-report "$OUT/sync_test.json" tests/rl/test_sync_free_gpu.py
step env_gpu 100 "$OUT/env_gpu.log" "$PY" benchmarks/env_gpu.py ${DEV[@]+"${DEV[@]}"} --num-envs $N "${STEPS[@]}" \
  --repeats 2
step profile_gpu 60 "$OUT/profile_gpu.log" "$PY" benchmarks/profile_gpu.py ${DEV[@]+"${DEV[@]}"} --num-envs $N \
  "${PSTEPS[@]}"
LEFT=$((DEADLINE - $(date +%s)))
if ((LEFT >= 30)); then
  echo "== gpu_suite tests (budget ${LEFT} s)"
  OUT="$OUT/suite" SUITE_SMOKE=${ISSUE25_SMOKE:-0} SUITE_PARTS=tests SUITE_BUDGET_S=$LEFT GPU_TESTS_S=$LEFT \
    SUITE_PYTEST_ARGS="--deselect tests/rl/test_sync_free_gpu.py" PYTHON="$PY" bash benchmarks/gpu_suite.sh \
    >/dev/null 2>&1
  tail -n 12 "$OUT/suite/suite.log"
  echo "gpu_suite ran null $(($(date +%s) - START))" >>"$STATUS"
else
  echo "gpu_suite skipped null 0" >>"$STATUS"
fi

"$PY" - "$OUT" <<'PY'
import json, os, sys
out = sys.argv[1]

def result(log):
    path = os.path.join(out, log)
    lines = [l for l in open(path, errors="replace") if l.startswith("RESULT ")] if os.path.exists(path) else []
    return json.loads(lines[-1][7:]) if lines else None

def load(path):
    path = os.path.join(out, path)
    return json.load(open(path)) if os.path.exists(path) else None

status = {}
for line in open(os.path.join(out, ".status")):
    name, state, rc, seconds = line.split()
    status[name] = {"status": state, "rc": None if rc == "null" else int(rc), "seconds": int(seconds)}
env, prof, sync, tests = result("env_gpu.log"), result("profile_gpu.log"), load("sync_test.json"), load("suite/gpu_tests.json")
row = ((env or {}).get("sizes") or [None])[0]
summary = {
    "parts": status,
    "sync_test": sync and {"summary": sync["summary"], "tests": sync["tests"]},
    "env_gpu": row and {k: row[k] for k in ("ratio", "env_ms_per_step", "raw_ms_per_step", "env_steps_per_s",
                                                   "syncs", "policy")},
    "env_gpu_target": env and env["target"],
    "profile": prof and {k: prof[k] for k in ("wall_ms_per_step", "host_round_trips", "torch_sync_warnings",
                                                    "device_busy_fraction", "policy")},
    "gpu_tests": tests and {"summary": tests["summary"], "selected": tests["selected"], "not_run": tests["not_run"],
                            "failed": {k: v for k, v in tests["tests"].items() if v["outcome"] in ("failed", "error")}},
    "device": (env or prof or {}).get("device"), "versions": (env or prof or {}).get("versions"),
}
json.dump(summary, open(os.path.join(out, "summary.json"), "w"), indent=1)
print(json.dumps(summary, indent=1)[:3000])
PY
rm -f "$STATUS"
