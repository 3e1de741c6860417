"""``TsdfMap``'s eager-torch integration path (``backend="torch"``): the reference that the Warp
kernels (``tsdf.kernels``) are tested against, and the fallback where Warp is not installed.

``_TorchIntegration`` is a base class of ``TsdfMap``: its methods read and write the map's storage and
hash. It holds the block allocation (``_allocate``, which the Warp path uses too where the depth range is
too deep for a dense volume of block cells), the selection of the surface blocks that the view may
clear and the per-voxel update, in the float32 operations the kernels copy one by one (edit the two
together). ``sample_depth`` is the plain sub-pixel depth lookup of the tests' brute-force reference.

Separate from ``tsdf/map.py`` so that the map's public API, storage and Warp dispatch read on their own.
"""

from __future__ import annotations

import torch

from . import kernels
from .block_hash import decode, encode
from .frame import _NO_DEPTH, _FrameBuffers, _FrameGeometry
from .launches import dropoff_scale

_MAX_STEP = kernels.MAX_STEP
"""Relative depth spread of a 2x2 pixel cell up to which the depth lookup interpolates."""


def sample_depth(depth: torch.Tensor, u: torch.Tensor, v: torch.Tensor,
                 max_step: float = 0.05) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """Depth at sub-pixel positions (u, v): bilinear between the 4 neighbouring pixels where all
    four are valid and within ``max_step`` (relative) of each other, else the nearest pixel (no
    blending across depth edges). Nearest-pixel lookup alone (Open3D) misplaces a grazing floor by
    up to half a pixel's depth change (~5 mm at 3 m). Returns depth (0 = none), the nearest pixel's
    flat index (for colour) and whether (u, v) is in the image."""
    h, w = depth.shape
    in_image = (u > -0.5) & (u < w - 0.5) & (v > -0.5) & (v < h - 0.5)
    ui, vi = torch.round(u).long().clamp_(0, w - 1), torch.round(v).long().clamp_(0, h - 1)
    nearest = vi * w + ui
    flat = depth.reshape(-1)
    d_near = torch.take(flat, nearest)
    u0, v0 = torch.floor(u).long().clamp_(0, w - 2), torch.floor(v).long().clamp_(0, h - 2)
    fu, fv = (u - u0).clamp(0, 1), (v - v0).clamp(0, 1)
    i00 = v0 * w + u0
    d00, d01, d10, d11 = (torch.take(flat, i00 + o) for o in (0, 1, w, w + 1))
    lo = torch.minimum(torch.minimum(d00, d01), torch.minimum(d10, d11))
    hi = torch.maximum(torch.maximum(d00, d01), torch.maximum(d10, d11))
    smooth = (lo > 0) & (hi - lo <= max_step * lo)
    bilinear = (d00 * (1 - fu) + d01 * fu) * (1 - fv) + (d10 * (1 - fu) + d11 * fu) * fv
    d = torch.where(smooth, bilinear, d_near)
    return torch.where(in_image, d, torch.zeros_like(d)), nearest, in_image


class _TorchIntegration:
    """``TsdfMap``'s torch path (block allocation, view selection, per-voxel update), mixed into the map:
    the methods use its ``cfg``, ``device``, ``hash``, ``num_blocks``, storage (``tsdf``, ``weight``,
    ``color``, ``updated``, ``has_surface``), local voxel offsets (``_local_m``, ``_local_index``),
    ``_grow``, ``_corner_blocks`` and ``_block_radius``."""

    def _allocate(self, depth: torch.Tensor, buf: _FrameBuffers, g: _FrameGeometry) -> torch.Tensor:
        """Allocate the blocks that the truncation band of every ``allocation_stride``-th valid pixel
        touches, and those in front of it along the free-space rays (``TsdfCfg.free_space_stride``);
        return their slots. Deduplicated sort-free, through a dense volume of block cells
        around the camera (``torch.unique`` only when the depth range makes that volume too big)."""
        s = self.cfg.allocation_stride
        # the band [d - trunc, d + trunc] along each ray: a block (>= 2 trunc here) is hit by one of 3
        # samples; block = floor(round(p / voxel) / B) = floor(p / block + 0.5 / B), in block units. Products
        # and sums one op each (no fused multiply-add), as the Warp kernel computes them
        m = torch.from_numpy(g.rot_blocks).to(self.device)
        rays_w = buf.rays[..., 0:1] * m[0] + buf.rays[..., 1:2] * m[1] + buf.rays[..., 2:3] * m[2]
        start = torch.from_numpy(g.start_blocks).to(self.device)
        d = depth[::s, ::s]
        valid = (d >= self.cfg.depth_min_m) & (d <= self.cfg.depth_max_m)  # False for NaN and inf too
        samples = torch.mul(rays_w, d[..., None] + buf.band).add_(start).floor_()
        valid = valid.expand(3, -1, -1)
        if self.cfg.carve_stride:
            # free space: every carve_stride-th allocation ray also at depths k step < d - trunc (the kernel's
            # float32 k * step), so the blocks between the camera and the band are allocated too
            cs, step = self.cfg.carve_stride, self.cfg.free_space_step_m
            rays_c, d_c, ok_c = rays_w[::cs, ::cs], d[::cs, ::cs], valid[0, ::cs, ::cs]
            k = torch.arange(int(self.cfg.depth_max_m / step) + 2, dtype=torch.float32, device=self.device)
            t = k.mul_(step)[:, None, None]  # (K, 1, 1)
            limit = d_c + buf.band[0, 0, 0]
            carve = torch.mul(rays_c, t[..., None]).add_(start).floor_()  # (K, h, w, 3)
            carve_ok = ok_c & (t < limit)
            samples = torch.cat([samples.reshape(-1, 3), carve.reshape(-1, 3)])
            valid = torch.cat([valid.reshape(-1), carve_ok.reshape(-1)])
        samples, valid = samples.reshape(-1, 3), valid.reshape(-1)
        if buf.volume is not None:
            side = 2 * buf.r_blocks + 1
            corner = torch.from_numpy(self._corner_blocks(buf, g)).to(self.device)
            cell = (samples - corner).clamp_(0, side - 1) @ buf.strides
            cell = torch.where(valid, cell, side ** 3).to(torch.int64)
            vol = buf.volume
            vol.zero_()
            vol.index_fill_(0, cell, True)
            vol[-1] = False
            flat = torch.nonzero(vol, as_tuple=True)[0]
            coords = torch.stack([flat // (side * side), (flat // side) % side, flat % side], -1) + corner.to(torch.int64)
        else:
            coords = decode(torch.unique(encode(samples[valid].to(torch.int64))))
        slots = self.hash.insert(coords)
        self._grow(len(self.hash))
        return slots

    def _blocks_in_view(self, depth: torch.Tensor, g: _FrameGeometry) -> torch.Tensor:
        """Slots of allocated blocks holding a surface that intersect the view and are not wholly
        behind the measured depth: the blocks where a moved obstacle may have to be cleared (the Warp
        path's ``select_blocks``, the same float32 operations)."""
        size = self.cfg.block_size_m
        cand = torch.nonzero(self.has_surface[: self.num_blocks], as_tuple=True)[0]
        centres = (self.hash.slot_coords[cand].to(torch.float32) + 0.5) * size - 0.5 * self.cfg.voxel_size_m
        rot, t = torch.from_numpy(g.rot_cw).to(self.device), torch.from_numpy(g.t_cw).to(self.device)
        cx, cy, cz = centres.unbind(1)
        x, y, z = (cx * rot[a, 0] + cy * rot[a, 1] + cz * rot[a, 2] + t[a] for a in range(3))
        radius, radius_px = self._block_radius(g)
        h, w = depth.shape
        zc = z.clamp(min=1e-3)
        k = g.k
        u = torch.round(x / zc * float(k[0, 0]) + float(k[0, 2])).long()
        v = torch.round(y / zc * float(k[1, 1]) + float(k[1, 2])).long()
        margin_px = zc.reciprocal().mul_(radius_px).long()
        near = (z + radius > self.cfg.depth_min_m) & (z - radius < self.cfg.depth_max_m)
        inside = (u + margin_px >= 0) & (u - margin_px < w) & (v + margin_px >= 0) & (v - margin_px < h)
        # keep blocks in front of (or in the band of) the surface seen near their centre; a block whose
        # centre pixel is off-image or empty is kept (cheap, and its voxels are checked one by one)
        d = depth[v.clamp(0, h - 1), u.clamp(0, w - 1)]
        valid = (d >= self.cfg.depth_min_m) & (d <= self.cfg.depth_max_m)
        keep = near & inside & (z > 0) & (~valid | (z - radius < d + self.cfg.truncation_m))
        return cand[keep]

    def _integrate_torch(self, depth: torch.Tensor, rgb: torch.Tensor | None, buf: _FrameBuffers,
                         g: _FrameGeometry) -> None:
        """``integrate`` in eager torch ops: allocate the band's blocks, then update the voxels of the new
        blocks and of the surface blocks in view."""
        h, w = depth.shape
        # padded copy with a 1-pixel _NO_DEPTH border, so a voxel projecting off the image reads a
        # depth far in front of it: no separate in-image test. Depth validity is checked per voxel, on
        # the few that are looked up, not on every pixel
        torch.nan_to_num(depth, nan=_NO_DEPTH, posinf=_NO_DEPTH, neginf=_NO_DEPTH, out=buf.depth_inner)
        if rgb is not None:
            buf.rgb[1:h + 1, 1:w + 1] = rgb
        new_slots = self._allocate(depth, buf, g)
        mask = torch.zeros(self.num_blocks, dtype=torch.bool, device=self.device)
        mask[new_slots] = True
        mask[self._blocks_in_view(depth, g)] = True
        slots = torch.nonzero(mask, as_tuple=True)[0]
        self._update_voxels_torch(slots, buf, g, rgb is not None)

    def _project(self, slots: torch.Tensor, g: _FrameGeometry) -> tuple[torch.Tensor, torch.Tensor]:
        """Homogeneous padded-pixel coordinates (K' [R | t] p) of every voxel centre as block origin +
        local offset: (3, n) of the blocks' origins and (3, B^3) of the local offsets, summed per voxel
        (one add instead of a product per voxel). The origins' products and sums one op each, as the
        Warp kernel computes them."""
        kr, kt = torch.from_numpy(g.kr).to(self.device), torch.from_numpy(g.kt).to(self.device)
        origin = (self.hash.slot_coords[slots] * self.cfg.block_voxels).to(torch.float32) * self.cfg.voxel_size_m
        ox, oy, oz = origin.unbind(1)
        origin_px = torch.stack([ox * kr[a, 0] + oy * kr[a, 1] + oz * kr[a, 2] + kt[a] for a in range(3)])
        return origin_px, torch.from_numpy(g.local_px).to(self.device)

    def _update_voxels_torch(self, slots: torch.Tensor, buf: _FrameBuffers, g: _FrameGeometry,
                             with_color: bool) -> None:
        """The per-voxel update in eager torch ops (the reference of the Warp kernel ``integrate_voxels``)."""
        cfg = self.cfg
        h, w = buf.shape
        wp = w + 2
        origin_px, local_px = self._project(slots, g)
        p = origin_px[:, :, None] + local_px[:, None, :]
        x, y, z = p.view(3, -1)
        zc = z.clamp(min=1e-6)
        trunc = cfg.truncation_m
        # sub-pixel position in the padded image (written over x, y), clamped so the 2x2 cell stays
        # inside it; anything off the image lands on the _NO_DEPTH border
        inv_z = zc.reciprocal()
        u = x.mul_(inv_z).clamp_(0.0, w + 0.75)
        v = y.mul_(inv_z).clamp_(0.0, h + 0.75)
        flat = buf.depth.view(-1)
        # 1. the nearest pixel's depth bounds the interpolated one: the 4 pixels are interpolated only
        # when within _MAX_STEP of each other (then |bilinear - nearest| <= _MAX_STEP * nearest), so a
        # voxel with (1 + _MAX_STEP) * nearest - z < -trunc can not be updated; keep only the others
        d_near = torch.take(flat, v.round().mul_(wp).add_(u.round()).to(torch.int64))
        cand = d_near.mul_(1.0 + _MAX_STEP) >= z - trunc
        sel = torch.nonzero(cand, as_tuple=True)[0]
        u, v, z = x.take(sel), y.take(sel), z.take(sel)
        # 2. the candidates: bilinear depth where the cell's 4 pixels are valid and within _MAX_STEP of
        # each other, else the nearest pixel (no blending across depth edges)
        u0, v0 = u.floor(), v.floor()
        fu, fv = u.sub_(u0), v.sub_(v0)
        i00 = v0.mul_(wp).add_(u0)
        near = fv.round().mul_(wp).add_(fu.round()).add_(i00).to(torch.int64)
        idx = i00.to(torch.int64)
        d00, d01 = torch.take(flat, idx), torch.take(flat[1:], idx)
        d10, d11 = torch.take(flat[wp:], idx), torch.take(flat[wp + 1:], idx)
        lo = torch.minimum(torch.minimum(d00, d01), torch.minimum(d10, d11))
        hi = torch.maximum(torch.maximum(d00, d01), torch.maximum(d10, d11))
        smooth = (hi <= lo * (1.0 + _MAX_STEP)) & (lo >= cfg.depth_min_m) & (hi <= cfg.depth_max_m)
        top = torch.addcmul(d00, fu, d01.sub_(d00))
        d = torch.addcmul(top, fv, torch.addcmul(d10, fu, d11.sub_(d10)).sub_(top))
        d = torch.where(smooth, d, torch.take(flat, near))
        sdf = d - z
        update = (sdf >= -trunc) & (d >= cfg.depth_min_m) & (d <= cfg.depth_max_m) & (z > 0)
        tsdf_new = (sdf * (1.0 / trunc)).clamp_(max=1.0)
        # 3. the update, gathered and scattered at the candidates' flat storage indices
        n, nv = slots.numel(), self._local_m.shape[1]
        vox = (slots[:, None] * nv + self._local_index).view(-1).take(sel)
        flat_t, flat_w = self.tsdf.view(-1), self.weight.view(-1)
        old_t, old_w = flat_t.take(vox), flat_w.take(vox)
        if cfg.clear_free_space:
            old_w.masked_fill_(update & (sdf >= trunc) & (old_t < 0), 0.0)
        if cfg.weight_ref_depth_m is None:
            w_obs = update.to(torch.float32)
        else:
            w_obs = torch.where(update, (cfg.weight_ref_depth_m / z.clamp(min=1e-6)).square_().clamp_(max=1.0), 0.0)
        if cfg.dropoff_m > 0.0:  # behind the surface by more than dropoff_m: less and less sure (voxblox)
            fade = (sdf + trunc) * dropoff_scale(trunc, cfg.dropoff_m)  # the kernel's float32 product
            w_obs = torch.where(sdf < -cfg.dropoff_m, w_obs * fade, w_obs)
        total = old_w.add_(w_obs)
        blend = w_obs.div_(total + 1e-12)
        flat_t.index_copy_(0, vox, torch.addcmul(old_t, blend, tsdf_new.sub_(old_t)))
        flat_w.index_copy_(0, vox, total.clamp_(max=cfg.max_weight))
        if with_color:
            # (M, 3) rows, blend expanded to the same contiguous shape (a broadcast over an inner
            # dimension of 3 is far slower on the CPU)
            colours = buf.rgb.view(-1, 3).index_select(0, near).to(torch.float32)
            flat_c = self.color.view(-1, 3)
            old_c = flat_c.index_select(0, vox).to(torch.float32)
            blend3 = blend[:, None].expand(-1, 3).contiguous()
            flat_c.index_copy_(0, vox, torch.addcmul(old_c, blend3, colours.sub_(old_c)).round_().to(torch.uint8))
        touched = torch.zeros(n * nv, dtype=torch.bool, device=self.device).index_copy_(0, sel, update)
        self.updated[slots] |= touched.view(n, nv).any(dim=1)
        # tsdf < 0 only ever with weight > 0
        self.has_surface[slots] = (self.tsdf.index_select(0, slots) < 0).any(dim=1)
