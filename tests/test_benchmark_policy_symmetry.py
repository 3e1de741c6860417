"""benchmarks/policy_symmetry.py: |pi(M o) - M pi(o)| over a policy's rollouts, zero for a policy symmetric by
construction and not for the shipped walker."""

import torch

from ambulo import envs
from ambulo.envs.symmetry import task_mirror
from ambulo.policies.shipped import load_policy
from ambulo.rl.symmetry import mirrored_obs
from script_loader import ROOT, load_script

bench = load_script(ROOT / "benchmarks" / "policy_symmetry.py")


def _run(policy, env, mirror, steps=40):
    return bench.summary(bench.measure(env, policy, mirror, steps), list(env.robot.joint_names))


def test_a_symmetrized_policy_measures_zero_and_the_shipped_walker_does_not():
    env = envs.make("humanoid-walk", num_envs=4, device="cpu", seed=3, play=True)
    mirror = task_mirror(env)
    shipped = load_policy("humanoid-walk")

    def raw(obs):
        return shipped(obs["policy"])

    def symmetrized(obs):  # (pi(o) + M pi(M o)) / 2 answers M o with M of its answer to o (M M = I)
        return 0.5 * (raw(obs) + mirror.actions(raw(mirrored_obs(obs, mirror))))

    exact = _run(symmetrized, env, mirror)
    env.reset()
    measured = _run(raw, env, mirror)
    assert exact["mirror_error"] < 1e-5 and exact["action_mean"] > 0.05
    assert measured["mirror_error"] > 100 * max(exact["mirror_error"], 1e-6)
    assert 0 < measured["ratio"] and len(measured["worst_joints"]) == 4


def test_the_error_is_averaged_per_sample_and_joint():
    sums = {"error": torch.tensor([2.0, 4.0], dtype=torch.float64),
            "magnitude": torch.tensor([4.0, 4.0], dtype=torch.float64), "samples": 2}
    out = bench.summary(sums, ["a", "b"], worst=1)
    # per joint: error 1, 2 -> mean 1.5; |action| 2, 2 -> mean 2; worst joint b
    assert out == {"mirror_error": 1.5, "action_mean": 2.0, "ratio": 0.75, "worst_joints": {"b": 2.0}}
