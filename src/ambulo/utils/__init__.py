"""Small shared helpers: rotation math (``math`` on torch tensors, ``rotations`` on NumPy
arrays), atomic file writes (``atomic``) and dotted config overrides (``overrides``)."""
