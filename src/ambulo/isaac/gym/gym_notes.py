"""What ambulo's ``Gym`` object does differently from Isaac Gym's, method by method: the tables the
unsupported methods' errors and docs/isaac-gym-coverage.md read."""

from __future__ import annotations

ISAAC_UNSUPPORTED: dict[str, str] = {
    "create_asset_box": "load a URDF/MJCF with the box instead (ambulo's importers make it one body)",
    "create_asset_sphere": "load a URDF/MJCF with the sphere instead",
    "create_asset_capsule": "load a URDF/MJCF with the capsule instead",
    "create_camera_sensor": "use ambulo.sensors' Camera / TiledCamera on the same model",
    "acquire_jacobian_tensor": "use mujoco.mj_jacBody on engine.get_data(world)",
    "acquire_mass_matrix_tensor": "use mujoco.mj_fullM on engine.get_data(world)",
    "acquire_force_sensor_tensor": "read forces with ambulo.sensors' ContactSensor on the model",
    "refresh_force_sensor_tensor": "read forces with ambulo.sensors' ContactSensor on the model",
    "refresh_jacobian_tensors": "use mujoco.mj_jacBody on engine.get_data(world)",
    "refresh_mass_matrix_tensors": "use mujoco.mj_fullM on engine.get_data(world)",
    "apply_rigid_body_force_at_pos_tensors": "set root velocities (set_actor_root_state_tensor) to push",
    "set_camera_location": "use ambulo.sensors' Camera / TiledCamera on the same model",
    "render_all_camera_sensors": "use ambulo.sensors' Camera / TiledCamera on the same model",
    "get_camera_image": "use ambulo.sensors' Camera / TiledCamera on the same model",
    "get_camera_image_gpu_tensor": "use ambulo.sensors' TiledCamera (batched images as tensors)",
    "set_sim_params": "create the sim with the SimParams it needs (the model is compiled once)",
}
"""Isaac Gym methods ambulo lacks -> what to use instead."""

ISAAC_APPROXIMATED: dict[str, str] = {
    "create_sim": "z-up only; SIM_FLEX fails; use_gpu_pipeline on a CUDA host runs MuJoCo Warp, else MuJoCo's CPU batch",
    "simulate": "one MuJoCo step per PhysX substep (dt / substeps): soft contacts and implicit PD drives, not PhysX TGS; "
                "static friction creeps slowly under load where PhysX's sticks",
    "create_env": "every env must create the same assets in the same order (one model in N worlds); "
                  "poses and DOF properties may differ per env",
    "create_actor": "collision group and filter are ignored: each env is its own world, so envs never collide",
    "load_asset": "URDF, MJCF or USD through ambulo's importers; a missing file named like a bundled asset "
                  "(assets/humanoid.urdf) loads that asset, with a warning; bodies and DOFs come in the file's "
                  "order (Isaac Gym can differ: it lists legged_gym's anymal_c legs LF, LH, RF, RH, the URDF "
                  "LF, RF, LH, RH)",
    "add_ground": "the plane's normal must be +z",
    "add_heightfield": "a MuJoCo hfield (sliding friction only; the transform's position, no rotation)",
    "add_triangle_mesh": "sampled into a MuJoCo hfield at the mesh's vertex spacing (highest surface per sample): "
                         "exact for height-function terrain at the vertices; vertical walls become one-sample slopes",
    "set_actor_dof_properties": "drive mode, stiffness, damping, armature, friction and limits per env; "
                                "velocity limits are not applied, effort limits are the file's (a URDF's "
                                "<limit effort> caps the joint's actuator force), not per-env values",
    "acquire_net_contact_force_tensor": "MuJoCo's net contact force per body from the last step's constraint solve",
    "acquire_dof_force_tensor": "the force each DOF's drive applies (MuJoCo's actuator force)",
    "create_viewer": "headless: a viewer that never closes and draws nothing",
    "draw_viewer": "headless: draws nothing (write_viewer_image_to_file renders env 0 on request)",
    "write_viewer_image_to_file": "renders env 0 only, with MuJoCo's offscreen renderer, at most 1280 x 960",
    "sync_frame_time": "headless: returns at once (no real-time pacing)",
    "set_actor_rigid_shape_properties": "friction (sliding, torsional, rolling) per env, sliding averaged with "
                                        "the ground's as PhysX combines it; restitution, offsets and filters are "
                                        "not applied",
    "set_asset_rigid_shape_properties": "as set_actor_rigid_shape_properties, for actors created afterwards",
    "set_actor_rigid_body_properties": "mass per env (the model's constants recomputed); com and inertia are kept",
    "apply_rigid_body_force_tensors": "MuJoCo's xfrc_applied at each body's centre of mass, for the next simulate",
    "begin_aggregate": "accepted, no effect (a PhysX broad-phase hint)",
    "set_rigid_body_color": "headless: colors are not drawn",
    "set_actor_dof_velocity_targets": "applied in velocity (and position) drive mode, as Isaac's",
}
"""Isaac Gym methods ambulo provides with a difference worth knowing -> the difference."""

__all__ = ["ISAAC_APPROXIMATED", "ISAAC_UNSUPPORTED"]
