"""ambulo: open robotics simulation and learning on MuJoCo."""

__version__ = "0.1.0"
