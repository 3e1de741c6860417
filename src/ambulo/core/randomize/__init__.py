"""Domain randomization: one layer under the replicator's randomizers and the RL task events.

- ``distributions``: the value sources (``Uniform``, ``Normal``, ``UniformInt``, ``Choice``,
  ``Constant``), drawn in batches from a seeded ``torch.Generator`` on the engine's device, or
  with NumPy from a ``numpy.random.Generator`` on the host (``sample_host``: the replicator's frames).
  ``ambulo.replicator`` re-exports them and Isaac's ``rep.distribution`` names wrap them.
- ``fields``: per-world model-field and state writes for row selectors (``core.rows``), one
  write per field: friction, mass, centre of mass, passive joint properties, colours and
  materials (``BodyGeoms``), joint positions within limits, free-body poses.
- ``actuators``: per-world drive gains and motor strength (``drive_gains``).
- ``placement``: the rejection loop that places bodies without overlap (``CollisionChecker``).

It sits in the core layer: it imports ``core`` and ``utils`` only.
"""

from .actuators import drive_gains, entity_actuator_ids
from .distributions import (
    Choice,
    Columns,
    Constant,
    Distribution,
    Normal,
    Uniform,
    UniformInt,
    as_distribution,
    as_generator,
    choice,
    constant,
    normal,
    sample_columns,
    uniform,
    uniform_int,
)
from .fields import (
    BodyGeoms,
    body_com_offset,
    body_mass,
    geom_friction,
    joint_dof_field,
    joint_range_box,
    match_bodies,
    randomize_field,
    subtree_geoms,
    write_field,
    write_free_poses,
)
from .placement import CollisionChecker, park_z, place_without_overlap

__all__ = ["BodyGeoms", "Choice", "CollisionChecker", "Columns", "Constant", "Distribution", "Normal", "Uniform",
           "UniformInt", "as_distribution", "as_generator", "body_com_offset", "body_mass", "choice",
           "constant", "drive_gains", "entity_actuator_ids", "geom_friction", "joint_dof_field",
           "joint_range_box", "match_bodies", "normal",
           "park_z", "place_without_overlap", "randomize_field", "sample_columns", "subtree_geoms",
           "uniform", "uniform_int", "write_field", "write_free_poses"]
