"""ambulo: open robotics simulation and learning on MuJoCo."""

# No GL backend is chosen here: MuJoCo binds MUJOCO_GL when ``mujoco`` is imported, and with
# MUJOCO_GL=egl on a machine without libEGL that import raises (PyOpenGL's AttributeError), which
# broke every command, training too (issue 22). ambulo.render.gl chooses at the first render.

__version__ = "0.1.0"
