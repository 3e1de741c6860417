"""benchmarks/fast_sac_update.py runs on the CPU at tiny sizes and reports what it measured."""

import json
import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]

OBS, CRITIC_OBS, ACTIONS, ACTOR_HIDDEN, CRITIC_HIDDEN, ATOMS, BATCH = 3, 4, 2, 5, 6, 7, 256


def expected_flops() -> int:
    """By hand, from the layer sizes: actor 3 -> 5 -> 4 (mean and log std of 2 actions),
    each critic (4 + 2) -> 6 -> 7 atoms; 2 FLOPs per multiply-add, batch 256, actor every 2nd update."""
    actor = OBS * ACTOR_HIDDEN + ACTOR_HIDDEN * 2 * ACTIONS  # 15 + 20 = 35 per row
    actor_first = OBS * ACTOR_HIDDEN  # 15: the observations need no gradient
    critic = (CRITIC_OBS + ACTIONS) * CRITIC_HIDDEN + CRITIC_HIDDEN * ATOMS  # 36 + 42 = 78 per row
    critic_first = (CRITIC_OBS + ACTIONS) * CRITIC_HIDDEN  # 36: the batch's inputs need no gradient
    critic_step = (actor + 2 * critic  # target: actor on next obs, two target critics
                   + 2 * critic  # two critics forward
                   + 2 * critic + 2 * (critic - critic_first))  # their weight and input gradients
    actor_step = (actor + 2 * critic  # actor forward, two critics on its actions
                  + 2 * critic + 2 * critic  # critics' weight and input gradients (actions need them)
                  + actor + (actor - actor_first))  # actor's weight and input gradients
    assert (critic_step, actor_step) == (587, 558)
    return 2 * BATCH * critic_step + 2 * BATCH * actor_step // 2


def test_fast_sac_update_benchmark_reports_times_phases_flops_and_kernels():
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT / "src"), os.environ.get("PYTHONPATH", "")]),
           "OMP_NUM_THREADS": "1"}
    run = subprocess.run([sys.executable, str(ROOT / "benchmarks" / "fast_sac_update.py"), "--device", "cpu",
                          "--batch-size", str(BATCH), "--updates", "6", "--warmup", "2", "--repeats", "2",
                          "--profile", "--profile-updates", "2", "--matmul-size", "256",
                          "--obs", str(OBS), "--critic-obs", str(CRITIC_OBS), "--actions", str(ACTIONS),
                          "--algo-cfg", "num_envs=16", "buffer_steps_per_env=16", f"num_atoms={ATOMS}",
                          f"actor_hidden_dims={ACTOR_HIDDEN}", f"critic_hidden_dims={CRITIC_HIDDEN}",
                          "policy_delay=2"],  # the hand count below: the actor every 2nd update
                         cwd=ROOT, env=env, capture_output=True, text=True, timeout=180)
    assert run.returncode == 0, run.stderr[-3000:]
    (line,) = [x for x in run.stdout.splitlines() if x.startswith("RESULT ")]
    result = json.loads(line[len("RESULT "):])
    entry = result["batches"][str(BATCH)]

    eager = entry["modes"]["eager"]
    assert eager["gpu_ms"] > 0 and eager["host_ms"] > 0 and eager["wall_ms"] > 0
    assert result["ceiling"]["tflops"] > 0 and entry["ceiling_ms"] > 0
    assert result["ratio"]["eager"] == entry["ceiling_ms"] / eager["gpu_ms"] > 0

    # the phases: every seam of the learner seen, all positive, their sum within the same run's time
    phases = entry["phases"]
    assert set(phases["ms"]) == {"sample", "critic.target", "critic.forward_loss", "critic.backward",
                                 "critic.clip", "critic.optimizer", "critic.stats", "actor.actor_forward",
                                 "actor.forward_loss", "actor.backward", "actor.clip", "actor.optimizer",
                                 "actor.alpha_stats", "polyak"}
    assert all(ms > 0 for ms in phases["ms"].values())
    assert phases["sum_ms"] <= phases["wall_ms"] * (1 + 1e-6)
    assert abs(sum(phases["groups"].values()) - phases["sum_ms"]) < 1e-9

    # the analytic matmul count, and the matmuls that really ran (float32 on the CPU: no autocast)
    want = expected_flops()
    assert entry["flops"]["per_update"] == want == entry["census"]["flops_per_update"]
    assert entry["census"]["float32_matmul"] is True

    profile = entry["profile"]
    assert 0 < len(profile["top"]) <= 15 and all(k["ms_per_update"] > 0 for k in profile["top"])
    assert any(k["name"] in ("aten::addmm", "aten::mm") and k["matmul"] for k in profile["top"])
    assert 0 < profile["matmul_ms_per_update"] < profile["total_ms_per_update"]
    assert profile["float32_matmul_ops"] > 0


def test_the_benchmark_times_updates_with_symmetry_on():
    """``--algo-cfg symmetry=true``: the learner mirrors half of each batch through stand-in maps of the
    task's sizes (no env is built), so the update cost includes the mirroring."""
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT / "src"), os.environ.get("PYTHONPATH", "")]),
           "OMP_NUM_THREADS": "1"}
    run = subprocess.run([sys.executable, str(ROOT / "benchmarks" / "fast_sac_update.py"), "--device", "cpu",
                          "--batch-size", "32", "--updates", "2", "--warmup", "1", "--repeats", "1",
                          "--matmul-size", "64", "--obs", str(OBS), "--critic-obs", str(CRITIC_OBS),
                          "--actions", str(ACTIONS), "--algo-cfg", "num_envs=16", "buffer_steps_per_env=16",
                          f"num_atoms={ATOMS}", f"actor_hidden_dims={ACTOR_HIDDEN}",
                          f"critic_hidden_dims={CRITIC_HIDDEN}", "symmetry=true"],
                         cwd=ROOT, env=env, capture_output=True, text=True, timeout=180)
    assert run.returncode == 0, run.stderr[-3000:]
    (line,) = [x for x in run.stdout.splitlines() if x.startswith("RESULT ")]
    result = json.loads(line[len("RESULT "):])
    assert result["cfg"]["symmetry"] is True and result["batches"]["32"]["modes"]["eager"]["gpu_ms"] > 0
