"""export: a trained policy as ONNX (checked with onnxruntime) and TorchScript.

Both files map a batch of policy observations (B, num_obs) float32 to actions
(B, num_actions), with the observation normalizer folded in and the batch size free.
"""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
import torch

from . import runs

ONNX_TOLERANCE = 1e-4
"""Largest |onnxruntime - torch| accepted; float32 MLPs agree to ~1e-6."""


def _sample_observations(env, num_steps: int = 20) -> torch.Tensor:
    """Real observations from a short random-action rollout (not just zeros)."""
    obs = [env.reset()]
    for _ in range(num_steps):
        actions = torch.randn(env.num_envs, env.num_actions, generator=env.generator,
                              dtype=torch.float64, device=env.device) * 0.5
        obs.append(env.step(actions)[0])
    return torch.cat(obs).cpu()


_LOAD_TORCHSCRIPT = """
import sys, numpy as np, torch
policy = torch.jit.load(sys.argv[1])
with torch.inference_mode():
    np.save(sys.argv[3], policy(torch.from_numpy(np.load(sys.argv[2]))).numpy())
"""


def _run_torchscript_in_fresh_process(path: Path, obs: np.ndarray) -> np.ndarray:
    """Load and run the TorchScript file the way a deployment would: in a new process.

    This also sidesteps an abort (``free(): invalid pointer``) of ``torch.jit.load`` in
    processes that imported ``mujoco.usd`` first.
    """
    with tempfile.TemporaryDirectory() as tmp:
        obs_file, out_file = Path(tmp) / "obs.npy", Path(tmp) / "actions.npy"
        np.save(obs_file, obs)
        subprocess.run([sys.executable, "-c", _LOAD_TORCHSCRIPT, str(path), str(obs_file),
                        str(out_file)], check=True)
        return np.load(out_file)


def export(run: str | os.PathLike, *, checkpoint: str | os.PathLike | None = None,
           out_dir: str | os.PathLike | None = None, log_root: str | os.PathLike = "runs") -> dict:
    """Write ``policy.onnx`` and ``policy.pt`` (TorchScript) for ``run``; return paths and diffs.

    The ONNX model is run with onnxruntime on real observations and compared with the torch
    policy; a difference above ``ONNX_TOLERANCE`` raises ``RuntimeError``.
    """
    import onnxruntime as ort

    run_dir, ckpt = runs.resolve_policy(run, checkpoint, log_root)
    info = runs.read_run_info(run_dir)
    env = runs.make_env_for_run(info, num_envs=16, device="cpu")
    runner = runs.load_runner(run_dir, env, ckpt)
    out = Path(out_dir) if out_dir else run_dir / "exported"
    out.mkdir(parents=True, exist_ok=True)
    policy = runner.get_inference_policy(device="cpu")

    jit_path = out / "policy.pt"
    scripted = torch.jit.script(policy.as_jit().to("cpu").eval())
    scripted.save(str(jit_path))

    onnx_path = out / "policy.onnx"
    onnx_model = policy.as_onnx(verbose=False).to("cpu").eval()
    batch = torch.export.Dim("batch")
    torch.onnx.export(
        onnx_model, onnx_model.get_dummy_inputs(), str(onnx_path), input_names=["obs"],
        output_names=["actions"], dynamic_shapes=({0: batch},), opset_version=18,
        external_data=False, verbose=False,
    )

    obs = _sample_observations(env)
    with torch.inference_mode():
        reference = onnx_model(obs).numpy()
    jit_actions = _run_torchscript_in_fresh_process(jit_path, obs.numpy())
    session = ort.InferenceSession(str(onnx_path), providers=["CPUExecutionProvider"])
    onnx_actions = session.run(["actions"], {"obs": obs.numpy()})[0]
    onnx_diff = float(np.max(np.abs(onnx_actions - reference)))
    jit_diff = float(np.max(np.abs(jit_actions - reference)))
    print(f"exported {ckpt.name} of {run_dir}:\n  {onnx_path}\n  {jit_path}\n"
          f"  onnxruntime vs torch on {len(obs)} observations: max abs diff {onnx_diff:.3g}\n"
          f"  TorchScript vs torch: max abs diff {jit_diff:.3g}")
    if onnx_diff > ONNX_TOLERANCE or jit_diff > ONNX_TOLERANCE:
        raise RuntimeError(f"exported policy disagrees with torch (onnx {onnx_diff:.3g}, "
                           f"jit {jit_diff:.3g} > {ONNX_TOLERANCE})")
    env.close()
    return {"onnx": onnx_path, "torchscript": jit_path, "checkpoint": ckpt,
            "onnx_max_abs_diff": onnx_diff, "torchscript_max_abs_diff": jit_diff,
            "num_obs": env.num_obs, "num_actions": env.num_actions}
