"""``pxr.PhysxSchema`` under ``ambulo run``: PhysX's applied APIs, authored on the stage as Isaac does.

usd-core has no PhysxSchema, so Isaac scripts' ``from pxr import PhysxSchema`` would fail.
While ``isaac_names()`` is active the hook answers ``pxr.PhysxSchema`` with a module built
here from the schema table (``ambulo.core.physx_attrs``): ``PhysxRigidBodyAPI.Apply(prim)``
adds ``PhysxRigidBodyAPI`` to the prim's ``apiSchemas`` and ``CreateLinearDampingAttr(0.5)``
authors ``float physxRigidBody:linearDamping = 0.5``, as PhysX's schema does. Which attributes
MuJoCo honours is ``ambulo.core.usd_physx``'s business, at the next ``reset()``.

usd-core's schema registry does not know these APIs, so ``prim.HasAPI(PhysxSchema.X)`` and
``prim.ApplyAPI(PhysxSchema.X)`` are taught them for the duration of the run (``install``),
and ``Get<Name>Attr().Get()`` returns the schema's fallback before the attribute is authored.
"""

from __future__ import annotations

import logging
import types

from ambulo.core.physx_attrs import APIS, NAMED_ONLY, PhysxApi, PhysxAttr

_log = logging.getLogger("ambulo.isaac")

_SDF_TYPES = {"float": "Float", "int": "Int", "uint": "UInt", "uint64": "UInt64", "bool": "Bool",
              "token": "Token", "vector3f": "Vector3f"}


def applied_schemas(prim) -> list[str]:
    """The prim's ``apiSchemas`` entries, unregistered ones included (``GetAppliedSchemas`` drops those)."""
    ops = prim.GetMetadata("apiSchemas") if prim and prim.IsValid() else None
    return list(ops.ApplyOperations([])) if ops is not None else []


class SchemaAttribute:
    """What ``Get<Name>Attr()`` returns while the attribute is not authored: ``Get()`` gives the
    schema's fallback (as a registered schema's built-in attribute would) and ``Set()`` authors
    it; anything else is asked of the authored ``Usd.Attribute``."""

    def __init__(self, schema: PhysxSchemaAPI, attr: PhysxAttr):
        self._schema, self._attr = schema, attr

    def Get(self, time=None):  # pxr's names
        authored = self._schema.GetPrim().GetAttribute(self.GetName())
        value = authored.Get() if authored else None
        return self._attr.fallback if value is None else value

    def Set(self, value, time=None) -> bool:
        return self._schema._author(self._attr, None).Set(value)

    def GetName(self) -> str:
        return self._schema._property_name(self._attr.name)

    def HasAuthoredValue(self) -> bool:
        authored = self._schema.GetPrim().GetAttribute(self.GetName())
        return bool(authored) and authored.HasAuthoredValue()

    def IsValid(self) -> bool:
        return bool(self._schema)

    __bool__ = IsValid

    def __getattr__(self, name: str):
        return getattr(self._schema._author(self._attr, None), name)


class PhysxSchemaAPI:
    """The base of the generated ``PhysxSchema.Physx*API`` classes (``UsdAPISchemaBase`` in pxr)."""

    _api: PhysxApi

    def __init__(self, prim=None, name: str | None = None):
        self._prim = prim.GetPrim() if hasattr(prim, "GetPrim") else prim
        self._instance = name

    def GetPrim(self):
        return self._prim

    def GetPath(self):
        return self._prim.GetPath()

    def GetName(self) -> str | None:
        """The instance name of a multiple-apply API (``PhysxLimitAPI(prim, "rotX")``)."""
        return self._instance

    def __bool__(self) -> bool:
        # as pxr's schema objects: valid when the prim is (whether the API is applied is HasAPI's)
        return self._prim is not None and self._prim.IsValid() and (
            not self._api.multiple_apply or bool(self._instance))

    def __repr__(self) -> str:
        return f"PhysxSchema.{type(self).__name__}({self._prim!r})"

    @classmethod
    def _entry(cls, name: str | None) -> str:
        return f"{cls._api.name}:{name}" if cls._api.multiple_apply else cls._api.name

    @classmethod
    def Apply(cls, prim, name: str | None = None):
        """Add the API to the prim's ``apiSchemas`` (as ``UsdPrim::ApplyAPI`` does) and return it."""
        if cls._api.multiple_apply and not name:
            raise ValueError(f"{cls._api.name} is a multiple-apply API: pass an instance name, "
                             f"e.g. {cls._api.name}.Apply(prim, 'rotX')")
        if not cls.CanApply(prim):
            raise ValueError(f"cannot apply {cls._api.name} to an invalid prim {prim!r}")
        if cls._entry(name) not in applied_schemas(prim):
            prim.AddAppliedSchema(cls._entry(name))
        if cls._api.name in NAMED_ONLY:
            _log.warning("%s on %s: MuJoCo has no counterpart; its attributes are authored and ignored",
                         cls._api.name, prim.GetPath())
        return cls(prim, name)

    @classmethod
    def CanApply(cls, prim, whyNot=None) -> bool:
        return prim is not None and prim.IsValid()

    @classmethod
    def Get(cls, stage, path, name: str | None = None):
        return cls(stage.GetPrimAtPath(path), name)

    @classmethod
    def GetSchemaAttributeNames(cls, includeInherited: bool = True, instanceName: str | None = None):
        return [cls._api.property_name(a.name, instanceName or "__INSTANCE_NAME__") for a in cls._api.attributes]

    def _property_name(self, name: str) -> str:
        return self._api.property_name(name, self._instance)

    def _author(self, attr: PhysxAttr, value):
        """The attribute on the prim with the schema's Sdf type (created if missing), set to ``value``."""
        from pxr import Sdf

        variability = Sdf.VariabilityUniform if attr.uniform else Sdf.VariabilityVarying
        created = self._prim.CreateAttribute(self._property_name(attr.name),
                                             getattr(Sdf.ValueTypeNames, _SDF_TYPES[attr.type_name]),
                                             False, variability)
        if value is not None:
            created.Set(value)
        return created


def _create_attr(attr: PhysxAttr):
    def create(self, defaultValue=None, writeSparsely: bool = False):
        if writeSparsely and defaultValue == attr.fallback and not SchemaAttribute(self, attr).HasAuthoredValue():
            return SchemaAttribute(self, attr)
        return self._author(attr, defaultValue)

    create.__name__ = f"Create{attr.method}Attr"
    create.__doc__ = f"Author ``{attr.type_name} <namespace>:{attr.name}`` (PhysX's fallback: {attr.fallback!r})."
    return create


def _get_attr(attr: PhysxAttr):
    def get(self):
        authored = self._prim.GetAttribute(self._property_name(attr.name))
        return authored if authored and authored.HasAuthoredValue() else SchemaAttribute(self, attr)

    get.__name__ = f"Get{attr.method}Attr"
    return get


def _rel(name: str, create: bool):
    def rel(self):
        path = self._property_name(name)
        return self._prim.CreateRelationship(path, False) if create else self._prim.GetRelationship(path)

    rel.__name__ = f"{'Create' if create else 'Get'}{name[0].upper()}{name[1:]}Rel"
    return rel


def _schema_class(api: PhysxApi) -> type:
    methods = {"_api": api, "__doc__": f"PhysX's ``{api.name}``: authors ``{api.namespace}:*`` attributes."}
    for attr in api.attributes:
        methods[f"Create{attr.method}Attr"] = _create_attr(attr)
        methods[f"Get{attr.method}Attr"] = _get_attr(attr)
    for rel in api.relationships:
        methods[_rel(rel, True).__name__] = _rel(rel, True)
        methods[_rel(rel, False).__name__] = _rel(rel, False)
    return type(api.name, (PhysxSchemaAPI,), methods)


SCHEMAS: dict[str, type] = {name: _schema_class(api) for name, api in APIS.items()}


def _tokens() -> types.SimpleNamespace:
    """``PhysxSchema.Tokens``: property names (``physxRigidBodyLinearDamping``) and allowed values."""
    tokens = {}
    for api in APIS.values():
        for attr in api.attributes:
            tokens[api.namespace + attr.method] = api.property_name(attr.name, "__INSTANCE_NAME__")
            if attr.type_name == "token" and attr.fallback:
                tokens[attr.fallback] = attr.fallback
    for value in ("TGS", "PGS", "GPU", "MBP", "SAP", "PCM", "SAT", "patch", "average", "min", "max", "multiply",
                  "easy", "constrained", "Synchronous", "Asynchronous", "Disabled", "X", "Y", "Z"):
        tokens[value] = value
    return types.SimpleNamespace(**tokens)


_patched: dict[str, object] = {}


def _is_ours(schema) -> bool:
    return isinstance(schema, type) and issubclass(schema, PhysxSchemaAPI)


def install() -> None:
    """Teach ``Usd.Prim.HasAPI`` / ``ApplyAPI`` / ``RemoveAPI`` the PhysxSchema classes (undone by ``restore``)."""
    from pxr import Usd

    if _patched:
        return
    for method in ("HasAPI", "ApplyAPI", "RemoveAPI"):
        _patched[method] = getattr(Usd.Prim, method)

    def has_api(prim, schema, *args, **kwargs):
        if not _is_ours(schema):
            return _patched["HasAPI"](prim, schema, *args, **kwargs)
        name = args[0] if args else kwargs.get("instanceName")
        entries = applied_schemas(prim)
        if schema._api.multiple_apply and not name:
            return any(e.startswith(schema._api.name + ":") for e in entries)
        return schema._entry(name) in entries

    def apply_api(prim, schema, *args, **kwargs):
        if not _is_ours(schema):
            return _patched["ApplyAPI"](prim, schema, *args, **kwargs)
        return bool(schema.Apply(prim, *args, **kwargs))

    def remove_api(prim, schema, *args, **kwargs):
        if not _is_ours(schema):
            return _patched["RemoveAPI"](prim, schema, *args, **kwargs)
        return prim.RemoveAppliedSchema(schema._entry(args[0] if args else kwargs.get("instanceName")))

    Usd.Prim.HasAPI, Usd.Prim.ApplyAPI, Usd.Prim.RemoveAPI = has_api, apply_api, remove_api


def restore() -> None:
    """Give ``Usd.Prim`` its own methods back (the end of an ``ambulo run``)."""
    if not _patched:
        return
    from pxr import Usd

    for method, original in _patched.items():
        setattr(Usd.Prim, method, original)
    _patched.clear()


def as_module(name: str = "pxr.PhysxSchema") -> types.ModuleType:
    """A fresh ``pxr.PhysxSchema`` module: the schema classes and ``Tokens``; installs the HasAPI patch."""
    module = types.ModuleType(name, __doc__)
    for cls_name, cls in SCHEMAS.items():
        setattr(module, cls_name, cls)
    module.Tokens = _tokens()
    module.__all__ = [*SCHEMAS, "Tokens"]
    install()
    return module


__all__ = ["SCHEMAS", "PhysxSchemaAPI", "SchemaAttribute", "applied_schemas", "as_module", "install", "restore"]
