"""MuJoCo C's heightfield contacts reduced the way MuJoCo Warp reduces them.

Why: both engines collide a geom with a heightfield prism by prism (two triangular prisms a cell,
each a convex solid with side walls down to the base). MuJoCo C (``mjc_ConvexHField``) keeps one
contact per prism the geom overlaps, up to 50; MuJoCo Warp (``collision_convex.ccd_hfield_kernel``)
computes the same per-prism contacts and keeps at most 4: the deepest, then the one furthest from
it, then the two spreading the patch most, stopping at one closer than 1 mm. A sole sphere that
overlaps a cell edge also "collides" with the neighbouring prism, whose nearest feature is its top
edge: that contact's normal points from the edge to the sphere's centre, tilted up to ~70 degrees
off the surface, though the surface there is flat or planar. On humanoid-rough's slope_down tiles
(a policy's states, both engines' own constraint solves in the same states) MuJoCo C gave 2.37
contacts per touching sole sphere (up to 7) against Warp's 1.68, and 3.7 times Warp's sideways
force for the same vertical force; a sphere sunk past its centre gets contacts 2 cm deep pointing
+-x, each worth kilonewtons. Policies are trained on Warp, which also limits such deep contacts
(``engine.warp_hfield``): humanoid-rough's session-18 walker fell in 0.17 and 0.38 of its episodes
on MuJoCo C's hfield tiles (two seeds) against 0.016 on Warp; reduced, 0.016 and 0.008.

``reduce_hfield_contacts(depth_m)`` replaces MuJoCo C's heightfield collision functions
(``mjCOLLISIONFUNC``, MuJoCo's public table of narrowphase functions) by a wrapper that calls the
original, keeps Warp's subset in Warp's order, and then, as ``engine.warp_hfield`` does on Warp,
turns a contact deeper than ``depth_m`` into one ``depth_m`` deep along the heightfield's up axis
at the other geom's centre. It is process-wide (every MjModel with a heightfield, every thread of
``mujoco.batch``). With numba installed the wrapper is a compiled C callback (no GIL; the CPU
engine's env-steps/s on hfield tiles unchanged: ``benchmarks/hfield_reduce_cost.py``); without, a
ctypes Python callback that takes the GIL for each geom-heightfield pair (4x slower there).
``enabled=False`` restores MuJoCo's own.
"""

from __future__ import annotations

import ctypes
import warnings
from pathlib import Path

import mujoco
import numpy as np

_NTYPES = int(mujoco.mjtGeom.mjNGEOMTYPES)
_HFIELD = int(mujoco.mjtGeom.mjGEOM_HFIELD)
_CONVEX = tuple(int(t) for t in (mujoco.mjtGeom.mjGEOM_SPHERE, mujoco.mjtGeom.mjGEOM_CAPSULE,
                                 mujoco.mjtGeom.mjGEOM_ELLIPSOID, mujoco.mjtGeom.mjGEOM_CYLINDER,
                                 mujoco.mjtGeom.mjGEOM_BOX, mujoco.mjtGeom.mjGEOM_MESH))
MAX_CONTACTS = 4
"""Warp's contacts per geom-heightfield pair."""
MIN_SEPARATION_M = 1.0e-3
"""Warp's ``MIN_DIST_TO_NEXT_CONTACT``: a further contact closer than this ends the selection."""


class _PreContact(ctypes.Structure):
    """``mjPreContact`` (mjdata.h): what a narrowphase function writes per contact."""

    _fields_ = [("dist", ctypes.c_double), ("pos", ctypes.c_double * 3), ("normal", ctypes.c_double * 3),
                ("tangent", ctypes.c_double * 3)]


_COLLISION_FN = ctypes.CFUNCTYPE(ctypes.c_int, ctypes.c_void_p, ctypes.c_void_p, ctypes.POINTER(_PreContact),
                                 ctypes.c_int, ctypes.c_int, ctypes.c_double)


def _library() -> ctypes.CDLL:
    """The libmujoco the ``mujoco`` module runs (dlopen returns the loaded one: one table)."""
    folder = Path(mujoco.__file__).parent
    found = sorted(folder.glob("libmujoco.so*")) or sorted(folder.glob("libmujoco*.dylib"))
    if not found:
        raise RuntimeError(f"reduce_hfield_contacts: no libmujoco in {folder}; this MuJoCo build is not supported")
    return ctypes.CDLL(str(found[0]))


def _pointer_offsets() -> tuple[int, int]:
    """Byte offsets of ``geom_xpos`` and ``geom_xmat`` in ``mjData``: the wrapper gets the raw
    ``mjData*`` and reads the geoms' poses there (found once, by matching a data's own buffers)."""
    model = mujoco.MjModel.from_xml_string("<mujoco><worldbody><geom size='1'/></worldbody></mujoco>")
    data = mujoco.MjData(model)
    want = {data.geom_xpos.ctypes.data: "xpos", data.geom_xmat.ctypes.data: "xmat"}
    found: dict[str, int] = {}
    base = data._address
    for offset in range(0, 1 << 20, ctypes.sizeof(ctypes.c_void_p)):  # stops inside the struct
        name = want.get(ctypes.c_void_p.from_address(base + offset).value)
        if name is not None:
            found[name] = offset
            if len(found) == 2:
                return found["xpos"], found["xmat"]
    raise RuntimeError("reduce_hfield_contacts: geom_xpos/geom_xmat not found in mjData")


_ROW = 10
"""Doubles in one ``mjPreContact``: dist, pos[3], normal[3], tangent[3]."""


def _reduce_rows(con, n, depth_m, centre, up):
    """Reduce ``n`` contacts (``con``: flat float64 rows of ``mjPreContact``) in place to Warp's
    subset in Warp's order (``ccd_hfield_kernel``: the deepest, the one furthest from it, the one
    furthest from their line, the one furthest from the triangle's edges; a next one closer than
    ``MIN_SEPARATION_M`` ends it), then limit each contact deeper than ``depth_m`` (> 0; else none)
    as ``engine.warp_hfield`` does: ``depth_m`` deep at ``centre`` along ``up``. Returns the count.
    Plain Python that numba compiles too (the callback's fast path)."""
    if n > 1:
        first = 0
        for i in range(1, n):
            if con[_ROW * i] < con[_ROW * first]:  # strict: the first of equal minima, as Warp
                first = i
        keep = np.full(MAX_CONTACTS, -1, np.int64)
        keep[0] = first
        k = 1
        o = _ROW * first
        p0x, p0y, p0z = con[o + 1], con[o + 2], con[o + 3]
        nx, ny, nz = con[o + 4], con[o + 5], con[o + 6]
        ax = ay = az = bx = by = bz = p1x = p1y = p1z = 0.0
        while k < MAX_CONTACTS:
            best, best_i = -np.inf, -1
            for i in range(n):
                taken = False
                for j in range(k):
                    taken = taken or keep[j] == i
                if taken:
                    continue
                dx, dy, dz = con[_ROW * i + 1] - p0x, con[_ROW * i + 2] - p0y, con[_ROW * i + 3] - p0z
                if k == 1:  # furthest from the deepest
                    score = np.sqrt(dx * dx + dy * dy + dz * dz)
                elif k == 2:  # furthest from the line of the first two
                    score = abs(dx * ax + dy * ay + dz * az)
                else:  # furthest from the triangle's other edges
                    ex, ey, ez = p1x - con[_ROW * i + 1], p1y - con[_ROW * i + 2], p1z - con[_ROW * i + 3]
                    score = abs(dx * ax + dy * ay + dz * az) + abs(ex * bx + ey * by + ez * bz)
                if score > best:
                    best, best_i = score, i
            if best_i < 0 or (0.0 < best < MIN_SEPARATION_M):
                break
            keep[k] = best_i
            k += 1
            q = _ROW * best_i
            if k == 2:  # a = normal x (p0 - p1)
                p1x, p1y, p1z = con[q + 1], con[q + 2], con[q + 3]
                ux, uy, uz = p0x - p1x, p0y - p1y, p0z - p1z
                ax, ay, az = ny * uz - nz * uy, nz * ux - nx * uz, nx * uy - ny * ux
            elif k == 3:  # a = normal x (p0 - p2), b = normal x (p1 - p2)
                p2x, p2y, p2z = con[q + 1], con[q + 2], con[q + 3]
                ux, uy, uz = p0x - p2x, p0y - p2y, p0z - p2z
                ax, ay, az = ny * uz - nz * uy, nz * ux - nx * uz, nx * uy - ny * ux
                vx, vy, vz = p1x - p2x, p1y - p2y, p1z - p2z
                bx, by, bz = ny * vz - nz * vy, nz * vx - nx * vz, nx * vy - ny * vx
        rows = np.empty(_ROW * MAX_CONTACTS)
        for j in range(k):
            for c in range(_ROW):
                rows[_ROW * j + c] = con[_ROW * keep[j] + c]
        for c in range(_ROW * k):
            con[c] = rows[c]
        n = k
    if depth_m > 0.0:
        for i in range(n):
            o = _ROW * i
            if con[o] < -depth_m:
                con[o] = -depth_m
                for c in range(3):
                    con[o + 1 + c] = centre[c]
                    con[o + 4 + c] = up[c]
                    con[o + 7 + c] = 0.0  # MuJoCo completes a frame whose tangent is zero
    return n


def _geom_frames(d: int, xpos_offset: int, xmat_offset: int, g1: int, g2: int):
    """(g2's centre, g1's z axis) from a raw ``mjData*`` (g1 is the heightfield: MuJoCo orders a
    pair by geom type)."""
    xpos = ctypes.c_void_p.from_address(d + xpos_offset).value
    xmat = ctypes.c_void_p.from_address(d + xmat_offset).value
    centre = np.frombuffer((ctypes.c_double * 3).from_address(xpos + 24 * g2), np.float64)
    rot = np.frombuffer((ctypes.c_double * 9).from_address(xmat + 72 * g1), np.float64)
    return centre, rot[2::3]


class _Reducer:
    """The installed wrapper: MuJoCo's original, the depth limit, the mjData offsets, and the
    callback (numba-compiled when numba is installed: no GIL, near MuJoCo's own speed; else a
    ctypes Python callback)."""

    def __init__(self, compiled: bool | None = None):
        self.table = (ctypes.c_void_p * (_NTYPES * _NTYPES)).in_dll(_library(), "mjCOLLISIONFUNC")
        self.original = {t: self.table[_HFIELD * _NTYPES + t] for t in _CONVEX}
        if len(set(self.original.values())) != 1:
            raise RuntimeError("reduce_hfield_contacts: this MuJoCo has several heightfield collision functions; "
                               "the wrapper supports one (mjc_ConvexHField)")
        self.xpos_offset, self.xmat_offset = _pointer_offsets()
        self.depth = (ctypes.c_double * 1)(-1.0)  # read by the callback at every call; <= 0: no limit
        original = next(iter(self.original.values()))
        self.compiled = _numba() is not None if compiled is None else compiled
        try:
            self.callback_address = self._compiled(original) if self.compiled else self._python(original)
        except Exception as err:  # a numba that cannot build the callback: the Python one, slower
            if compiled:
                raise
            warnings.warn(f"reduce_hfield_contacts: numba callback failed ({err}); using the slower Python one",
                          stacklevel=3)
            self.compiled = False
            self.callback_address = self._python(original)

    def _python(self, original_address: int) -> int:
        original = _COLLISION_FN(original_address)
        depth, xpos_offset, xmat_offset = self.depth, self.xpos_offset, self.xmat_offset

        def collide(m, d, con, g1, g2, margin):
            n = original(m, d, con, g1, g2, margin)
            if n > 1 or (n == 1 and depth[0] > 0.0 and con[0].dist < -depth[0]):
                rows = np.ctypeslib.as_array(ctypes.cast(con, ctypes.POINTER(ctypes.c_double)), (_ROW * n,))
                centre, up = _geom_frames(d, xpos_offset, xmat_offset, g1, g2)
                n = _reduce_rows(rows, n, depth[0], centre, up)
            return n

        self._keep = _COLLISION_FN(collide)  # alive as long as installed
        return ctypes.cast(self._keep, ctypes.c_void_p).value

    def _compiled(self, original_address: int) -> int:
        nb = _numba()
        from numba import types

        reduce_rows = nb.njit(_reduce_rows, nogil=True)
        as_pointer = _pointer_intrinsic()
        original = ctypes.CFUNCTYPE(ctypes.c_int, ctypes.c_void_p, ctypes.POINTER(ctypes.c_uint64),
                                    ctypes.POINTER(ctypes.c_double), ctypes.c_int, ctypes.c_int,
                                    ctypes.c_double)(original_address)
        depth_address = ctypes.addressof(self.depth)
        xpos_slot, xmat_slot = self.xpos_offset // 8, self.xmat_offset // 8
        sig = types.intc(types.voidptr, types.CPointer(types.uint64), types.CPointer(types.float64), types.intc,
                         types.intc, types.float64)

        @nb.cfunc(sig, nopython=True)
        def collide(m, d, con, g1, g2, margin):
            n = original(m, d, con, g1, g2, margin)
            depth_m = nb.carray(as_pointer(np.uint64(depth_address)), 1)[0]
            if n > 1 or (n == 1 and depth_m > 0.0 and con[0] < -depth_m):
                xpos = nb.carray(as_pointer(d[xpos_slot]), 3 * (g2 + 1))
                xmat = nb.carray(as_pointer(d[xmat_slot]), 9 * (g1 + 1))
                centre = xpos[3 * g2:3 * g2 + 3]
                up = np.array([xmat[9 * g1 + 2], xmat[9 * g1 + 5], xmat[9 * g1 + 8]])
                n = reduce_rows(nb.carray(con, _ROW * n), n, depth_m, centre, up)
            return n

        self._keep = collide  # alive as long as installed
        return collide.address

    def install(self, depth_m: float | None) -> None:
        self.depth[0] = -1.0 if depth_m is None else depth_m
        for t in _CONVEX:
            self.table[_HFIELD * _NTYPES + t] = self.callback_address

    def uninstall(self) -> None:
        for t, p in self.original.items():
            self.table[_HFIELD * _NTYPES + t] = p


def _numba():
    try:
        import numba
    except ImportError:
        return None
    return numba


def _pointer_intrinsic():
    """A numba intrinsic: a uint64 address as a float64 pointer (the callback reads MuJoCo's arrays)."""
    from numba import types
    from numba.extending import intrinsic

    @intrinsic
    def as_pointer(typingctx, address):
        sig = types.CPointer(types.float64)(types.uint64)

        def codegen(context, builder, signature, args):
            return builder.inttoptr(args[0], context.get_value_type(types.CPointer(types.float64)))

        return sig, codegen

    return as_pointer


_reducer: _Reducer | None = None


def reduce_hfield_contacts(depth_m: float | None, enabled: bool = True, *, compiled: bool | None = None) -> None:
    """MuJoCo C's geom-heightfield contacts in this process as MuJoCo Warp's: at most 4 a pair,
    Warp's subset, and none deeper than ``depth_m`` m (None: no depth limit). ``enabled=False``
    restores MuJoCo's own collision functions. Set it before stepping; it holds for every model.
    ``compiled``: the numba callback (None: when numba is installed) or the ctypes Python one
    (same contacts; the first install in a process picks it)."""
    global _reducer
    if depth_m is not None and not depth_m > 0.0:
        raise ValueError(f"hfield contact depth limit {depth_m!r}: pass a depth > 0 in m, e.g. 0.02, or None")
    if not enabled:
        if _reducer is not None:
            _reducer.uninstall()
        return
    if _reducer is None or (compiled is not None and compiled != _reducer.compiled):
        if _reducer is not None:
            _reducer.uninstall()
        _reducer = _Reducer(compiled)
    _reducer.install(None if depth_m is None else float(depth_m))


__all__ = ["MAX_CONTACTS", "MIN_SEPARATION_M", "reduce_hfield_contacts"]
