"""Policies that ship with ambulo: trained networks in the package's assets, with their contract.

A shipped policy lives in ``assets/data/policies/<task>/`` (the files are bundled assets; this module
is their reader): ``policy.onnx`` and ``policy.pt``
(TorchScript) map policy observations (B, num_obs) float32 to actions (B, num_actions), the
observation normalizer folded in; ``contract.json`` says how to build those observations and
use those actions without the training code: the observation terms in order with their sizes
and scales, the joint order, the default pose, the action scale and the control period, plus
where the policy came from (run, checkpoint, commit) and how it evaluated.

``load_policy(task)`` gives a ``ShippedPolicy``: call it on a (B, num_obs) tensor to get
(B, num_actions) actions, on the CPU through onnxruntime (the ``rl`` extra) and TorchScript
when onnxruntime is missing.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch

from .. import assets
from ..robots.humanoid import POLICY_TASK

POLICY_DIR = assets.POLICIES_DIR
"""One folder per shipped policy, named after its task with '_' for '-'."""


def shipped_tasks() -> list[str]:
    """Tasks with a shipped policy (folder names use '_' for the task name's '-')."""
    if not POLICY_DIR.is_dir():
        return []
    return sorted(p.name.replace("_", "-") for p in POLICY_DIR.iterdir() if (p / "contract.json").is_file())


def policy_dir(task: str) -> Path:
    """The folder of ``task``'s shipped policy (FileNotFoundError naming the shipped ones)."""
    folder = assets.policy_folder(task)
    if not (folder / "contract.json").is_file():
        raise FileNotFoundError(f"no shipped policy for task {task!r}; shipped: {', '.join(shipped_tasks()) or 'none'}")
    return folder


@dataclass
class ShippedPolicy:
    """A shipped policy: ``policy(obs)`` (B, num_obs) -> (B, num_actions) float32 actions."""

    task: str
    contract: dict[str, Any]
    folder: Path

    def __post_init__(self) -> None:
        self._session = None
        self._jit = None
        try:
            import onnxruntime as ort

            options = ort.SessionOptions()
            options.intra_op_num_threads = 1  # a 72x256 MLP: threads cost more than they give
            self._session = ort.InferenceSession(str(self.folder / "policy.onnx"), options,
                                                 providers=["CPUExecutionProvider"])
        except ImportError:
            self._jit = torch.jit.load(str(self.folder / "policy.pt"), map_location="cpu").eval()

    @property
    def num_obs(self) -> int:
        return int(self.contract["num_obs"])

    @property
    def num_actions(self) -> int:
        return int(self.contract["num_actions"])

    def __call__(self, obs: torch.Tensor) -> torch.Tensor:
        if obs.ndim != 2 or obs.shape[1] != self.num_obs:
            raise ValueError(f"the {self.task} policy takes (B, {self.num_obs}) observations, got "
                             f"{tuple(obs.shape)}; build them as contract.json's observation terms say")
        if self._session is not None:
            x = obs.detach().to("cpu", torch.float32).numpy()
            actions = self._session.run(["actions"], {"obs": np.ascontiguousarray(x)})[0]
            return torch.from_numpy(actions).to(obs.device)
        with torch.inference_mode():
            return self._jit(obs.detach().to("cpu", torch.float32)).to(obs.device)


def contract_terms(policy: ShippedPolicy, terms: tuple[str, ...], runner: str, source_task: str) -> dict[str, dict]:
    """The observation terms of ``policy``'s contract by name, after checking they are ``terms`` in that
    order (what ``runner`` builds); ``ValueError`` naming the fix (re-export from a ``source_task`` run)."""
    listed = [t["name"] for t in policy.contract["observation_terms"]]
    if tuple(listed) != terms:
        raise ValueError(f"the {policy.task} policy's contract lists observation terms {listed}; {runner} builds "
                         f"{list(terms)} (the {source_task} task's): re-export the policy from a {source_task} run")
    return {t["name"]: t for t in policy.contract["observation_terms"]}


def read_contract(task: str = POLICY_TASK) -> dict[str, Any]:
    """``task``'s ``contract.json`` as a dict, without loading the network."""
    return json.loads((policy_dir(task) / "contract.json").read_text())


def load_policy(task: str = POLICY_TASK) -> ShippedPolicy:
    """The shipped policy of ``task`` (FileNotFoundError naming the shipped ones)."""
    return ShippedPolicy(task, read_contract(task), policy_dir(task))


__all__ = ["POLICY_DIR", "ShippedPolicy", "contract_terms", "load_policy", "policy_dir", "read_contract", "shipped_tasks"]
