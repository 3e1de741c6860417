"""Running Isaac Sim scripts unchanged (``ambulo run script.py``).

Isaac scripts import ``isaacsim.*``, ``omni.isaac.*``, ``omni.*`` and ``carb``. Under
``ambulo run`` an import hook (``hook.py``) answers those names from the table in
``names.py`` with ambulo's objects; nothing is installed under those names, so outside
``ambulo run`` they do not exist and cannot shadow a real Isaac Sim install.
"""

from .hook import IsaacNameError, isaac_names
from .runner import run_script

__all__ = ["IsaacNameError", "isaac_names", "run_script"]
