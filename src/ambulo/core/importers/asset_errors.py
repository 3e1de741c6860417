"""The errors a robot/scene file raises when ambulo cannot load it as the file says.

They live in their own module so that every importer (``importers``, ``urdf``, ``usd``,
``meshes``) raises the same classes without importing each other.
"""

from __future__ import annotations


class AssetError(ValueError):
    """A robot/scene file is missing, of an unknown kind, or malformed."""


class AssetNotFoundError(AssetError, FileNotFoundError):
    """A file the robot needs (the robot file itself, a mesh, a package) does not exist.

    Also a ``FileNotFoundError`` so that code catching the OS error still catches it."""


class MeshConversionError(AssetError):
    """A mesh in a format MuJoCo cannot read could not be converted to one it can."""
