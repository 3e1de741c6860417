"""Per-world drive randomization: PD gains and motor strength of an entity's joint drives.

An ambulo drive (``core.drives``) is ``tau = kp (q* - q) + kd (qd* - qd) + tau_ff`` clipped to
the actuator's force range, with ``-kp, -kd`` in ``actuator_biasprm[:, 1:3]`` and
``Entity.set_joint_targets`` writing ``ctrl = kp q* + ...`` from each world's own gains. So:

- a gain scale multiplies ``kp`` (or ``kd``) and nothing else;
- a motor strength ``s`` multiplies the whole torque: ``s tau`` = gains ``s kp``, ``s kd`` (the
  feed-forward torque the caller scales itself) and a force range ``s`` times as wide (a weaker
  motor saturates sooner), legged_gym's ``motor_strength``.

Both are factors of the compiled model's nominal values, drawn per world and per joint, so drawing
again never compounds; the three are combined into one write per field.
"""

from __future__ import annotations

import torch

from .distributions import Distribution
from .fields import Rows, count_rows, index_array, nominal_values, write_field


def entity_actuator_ids(entity, joints=None):
    """Model actuator ids of the drives of ``entity``'s ``joints`` (indices into its joints; None: all)."""
    ids = index_array(entity.actuator_idx, entity.engine.model.nu)
    return ids if joints is None else ids[joints]


def drive_gains(entity, generator: torch.Generator, *, kp_scale: Distribution | None = None,
                kd_scale: Distribution | None = None, strength: Distribution | None = None, joints=None,
                rows: Rows = None, nominal_world: int | None = None,
                dtype: torch.dtype = torch.float64) -> dict[str, torch.Tensor]:
    """Draw and write per-world factors of ``entity``'s drive gains and strength.

    ``nominal_world``: read the nominal gains and force ranges from this world's current values
    instead of the compiled model, for a task that sets its gains per world after compiling
    (g1-walk's URDF-derived gains); the factors then apply to what is there, so draw only once.

    Returns the drawn factors by name (``"kp_scale"``, ``"kd_scale"``, ``"strength"``: those
    given), each ``(n, k)`` for ``n`` selected worlds and ``k`` joints, in the draw order
    kp, kd, strength."""
    if entity.actuator_idx is None:
        raise ValueError(f"{entity.prim_path} has joints without ambulo drives; its gains cannot be randomized")
    engine = entity.engine
    ids = entity_actuator_ids(entity, joints)
    n, k = count_rows(rows, engine.num_worlds), len(ids)
    factors = {name: dist.sample(generator, n * k, dtype=dtype).reshape(n, k)
               for name, dist in (("kp_scale", kp_scale), ("kd_scale", kd_scale), ("strength", strength))
               if dist is not None}
    if not factors:
        return factors
    bias = engine.model_field("actuator_biasprm")
    forcerange = engine.model_field("actuator_forcerange")

    def nominal(name, field, column=None):
        if nominal_world is None:
            return nominal_values(engine, name, ids, column=column, dtype=field.dtype)
        values = field[nominal_world, torch.as_tensor(ids, device=field.device)]
        return (values if column is None else values[..., column]).clone()

    one = torch.ones((), dtype=dtype, device=torch.device(engine.device))
    s = factors.get("strength", one)
    gains = {column: nominal("actuator_biasprm", bias, column) for column in (1, 2)}
    ranges = nominal("actuator_forcerange", forcerange)
    for column, name in ((1, "kp_scale"), (2, "kd_scale")):
        if name in factors or "strength" in factors:
            value = gains[column] * (factors.get(name, one) * s).to(gains[column])
            write_field(bias[..., column], value, rows=rows, index=ids)
    if "strength" in factors:
        write_field(forcerange, ranges * s.to(ranges)[..., None], rows=rows, index=ids)
    return factors


__all__ = ["drive_gains", "entity_actuator_ids"]
