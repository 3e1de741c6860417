"""The bundled robots' facts: names of their elements, where the apps place them, the numbers of
their geometry and of the policies that ship for them, each stated once (``humanoid``).

Content, not an app: this package imports ``ambulo.assets`` (and may import ``sensors``, ``core`` and
``utils``) only, so every app (walking, perception, the replicator, the ROS 2 bridge, the RL
tasks, the demo) reads the same facts."""
