"""The pose refinement (``vo.refine.refine_pose_torch``) on CUDA as captured graphs.

On a GPU the refinement is launch-bound: ~35 small kernels an iteration, four iterations, twice a
frame (more after a prior re-solve), each kernel a few microseconds of work behind ~10 us of host
time. A CUDA graph replays all of them with one launch. The number of correspondences changes
every call, so the inputs are padded to a power of two (at least 64) with rows that are not used
(weight 0: they add nothing to the normal equations) and one graph is captured per padded size,
when first needed; the result is the eager refinement's to rounding (the padded rows add exact
zeros).
"""

from __future__ import annotations

import torch

from .config import VoCfg
from .refine import refine_pose_torch

MIN_CAPACITY = 64


class _RefineGraph:
    """One captured refinement over ``capacity`` correspondence rows."""

    def __init__(self, capacity: int, cfg: VoCfg, device: torch.device):
        f64 = dict(dtype=torch.float64, device=device)
        self.rows = torch.zeros(capacity, 10, **f64)
        """(C, 10): points_w (3), pixels (2), points_c (3), has_depth, use (1.0 or 0.0)."""
        self.pose_k = torch.zeros(21, **f64)
        """(21,): rot_cw (9, row-major), t_cw (3), K (9, row-major)."""
        self.pose_k[:9] = torch.eye(3, **f64).flatten()
        self.pose_k[12:] = torch.eye(3, **f64).flatten()
        self.cfg = cfg
        side = torch.cuda.Stream(device)
        side.wait_stream(torch.cuda.current_stream(device))
        with torch.cuda.stream(side):  # warm-up: cuBLAS / cuSOLVER handles and the cached bases
            self._refine()
        torch.cuda.current_stream(device).wait_stream(side)
        self.graph = torch.cuda.CUDAGraph()
        with torch.cuda.graph(self.graph):
            self.rot_out, self.t_out = self._refine()

    def _refine(self) -> tuple[torch.Tensor, torch.Tensor]:
        r, p = self.rows, self.pose_k
        return refine_pose_torch(p[:9].view(3, 3), p[9:12], r[:, 0:3], r[:, 3:5], r[:, 5:8], r[:, 8] > 0.5,
                                 r[:, 9] > 0.5, p[12:].view(3, 3), self.cfg)

    def __call__(self, rot_cw, t_cw, points_w, pixels, points_c, has_depth, use, k):
        n = len(points_w)
        self.rows[n:].zero_()
        torch.cat([points_w, pixels, points_c, has_depth[:, None], use[:, None]], 1, out=self.rows[:n])
        torch.cat([rot_cw.flatten(), t_cw, k.flatten()], out=self.pose_k)
        self.graph.replay()
        return self.rot_out.clone(), self.t_out.clone()


class GraphRefiner:
    """``refine_pose_torch`` with the same arguments, replayed from CUDA graphs (module doc)."""

    def __init__(self, cfg: VoCfg, device: torch.device):
        self.cfg, self.device = cfg, torch.device(device)
        self.graphs: dict[int, _RefineGraph] = {}

    def __call__(self, rot_cw, t_cw, points_w, pixels, points_c, has_depth, use, k, cfg: VoCfg | None = None):
        if cfg is not None and cfg is not self.cfg:
            raise ValueError("GraphRefiner: the graphs were captured with another VoCfg; make a GraphRefiner for it")
        n = len(points_w)
        capacity = max(MIN_CAPACITY, 1 << max(n - 1, 0).bit_length())
        graph = self.graphs.get(capacity)
        if graph is None:
            graph = self.graphs[capacity] = _RefineGraph(capacity, self.cfg, self.device)
        return graph(rot_cw, t_cw, points_w, pixels, points_c, has_depth, use, k)


__all__ = ["GraphRefiner"]
