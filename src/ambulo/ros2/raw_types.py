"""ROS 2 message types that have no Python wheel (``tf2_msgs/msg/TFMessage``), made at run time.

rclpy needs a message class whose metaclass holds ``_TYPE_SUPPORT``, a capsule around a C
``rosidl_message_type_support_t``. For a type without a generated package we build that struct
with ctypes: identifier ``rosidl_typesupport_fastrtps_c``, callbacks naming the DDS type
(``tf2_msgs::msg::dds_::TFMessage_``, what every ROS 2 RMW puts on the wire) and the type's
RIHS01 hash and description, derived from the message definition exactly as ``rosidl`` does
(``hash_of`` equals ``rosbags``' ``hash_rihs01``, checked in tests). The class can only
publish and take *serialized* messages (``publisher.publish(cdr_bytes)``,
``create_subscription(..., raw=True)``): the bridge writes the CDR bytes itself (``cdr.py``).
A stock rviz2 or ``tf2_ros`` node sees an ordinary ``tf2_msgs/msg/TFMessage`` publisher.
"""

from __future__ import annotations

import ctypes
import functools
import hashlib
import json

from rosbags.typesys import Stores, get_typestore
from rosbags.typesys.base import Nodetype

_TIDS = {"int8": 2, "uint8": 3, "int16": 4, "uint16": 5, "int32": 6, "uint32": 7, "int64": 8, "uint64": 9,
         "float32": 10, "float64": 11, "float128": 12, "char": 13, "bool": 15, "byte": 16, "string": 17,
         "bounded_string": 21}
"""rosidl ``FieldType`` ids (``type_description_interfaces/msg/FieldType.msg``); arrays add 48,
bounded sequences 96, unbounded sequences 144."""


@functools.cache
def typestore():
    """The message definitions of ROS 2 Kilted (the distro of the PyPI wheels)."""
    return get_typestore(Stores.ROS2_KILTED)


def type_description(typename: str) -> dict:
    """``{"type_description": ..., "referenced_type_descriptions": [...]}`` of ``typename``, the
    structure whose JSON the RIHS01 hash is taken over (REP 2011, ``rosidl_generator_type_description``)."""
    store, structs = typestore(), {}

    def field(name: str, desc) -> dict:
        increment, capacity, string_capacity, nested = 0, 0, 0, ""
        kind, rest = desc
        if kind == Nodetype.ARRAY:
            increment, capacity = 48, rest[1]
            kind, rest = rest[0]
        elif kind == Nodetype.SEQUENCE:
            increment, capacity = (96, rest[1]) if rest[1] else (144, 0)
            kind, rest = rest[0]
        if kind == Nodetype.NAME:
            tid, nested = increment + 1, rest
            struct(rest)
        elif rest[0] == "string" and rest[1]:
            tid, string_capacity = increment + _TIDS["bounded_string"], rest[1]
        else:
            tid = increment + _TIDS[rest[0]]
        return {"name": name, "type": {"type_id": tid, "capacity": capacity, "string_capacity": string_capacity,
                                       "nested_type_name": nested}}

    def struct(name: str) -> dict:
        if name not in structs:
            fields = store.fielddefs[name][1] or [("structure_needs_at_least_one_member", (Nodetype.BASE, ("uint8", 0)))]
            structs[name] = {"type_name": name, "fields": [field(n, d) for n, d in fields]}
        return structs[name]

    top = struct(typename)
    return {"type_description": top,
            "referenced_type_descriptions": [s for n, s in sorted(structs.items()) if n != typename]}


def hash_of(typename: str) -> str:
    """``RIHS01_<sha256>`` of ``typename``: what ``ros2 topic info -v`` shows and RMWs match on."""
    return "RIHS01_" + hashlib.sha256(json.dumps(type_description(typename)).encode()).hexdigest()


# -- the C structs (rosidl_runtime_c, rosidl_typesupport_fastrtps_cpp headers of Kilted) ------------
class _String(ctypes.Structure):
    _fields_ = [("data", ctypes.c_char_p), ("size", ctypes.c_size_t), ("capacity", ctypes.c_size_t)]


class _FieldType(ctypes.Structure):
    _fields_ = [("type_id", ctypes.c_uint8), ("capacity", ctypes.c_uint64), ("string_capacity", ctypes.c_uint64),
                ("nested_type_name", _String)]


class _Field(ctypes.Structure):
    _fields_ = [("name", _String), ("type", _FieldType), ("default_value", _String)]


def _sequence(item):
    return type(f"_{item.__name__}Seq", (ctypes.Structure,), {
        "_fields_": [("data", ctypes.POINTER(item)), ("size", ctypes.c_size_t), ("capacity", ctypes.c_size_t)]})


class _Individual(ctypes.Structure):
    _fields_ = [("type_name", _String), ("fields", _sequence(_Field))]


class _TypeDescription(ctypes.Structure):
    _fields_ = [("type_description", _Individual), ("referenced_type_descriptions", _sequence(_Individual))]


class _TypeSourceSeq(ctypes.Structure):
    _fields_ = [("data", ctypes.c_void_p), ("size", ctypes.c_size_t), ("capacity", ctypes.c_size_t)]


class _Hash(ctypes.Structure):
    _fields_ = [("version", ctypes.c_uint8), ("value", ctypes.c_uint8 * 32)]


_CDR = ctypes.CFUNCTYPE(ctypes.c_bool, ctypes.c_void_p, ctypes.c_void_p)
_SIZE = ctypes.CFUNCTYPE(ctypes.c_uint32, ctypes.c_void_p)
_MAX_SIZE = ctypes.CFUNCTYPE(ctypes.c_size_t, ctypes.POINTER(ctypes.c_char))
_GETTER = ctypes.CFUNCTYPE(ctypes.c_void_p, ctypes.c_void_p)


class _Callbacks(ctypes.Structure):
    """``message_type_support_callbacks_t``: the DDS type name plus (de)serializers that are never
    called, since only serialized messages pass through this type."""

    _fields_ = [("message_namespace", ctypes.c_char_p), ("message_name", ctypes.c_char_p),
                ("cdr_serialize", _CDR), ("cdr_deserialize", _CDR), ("get_serialized_size", _SIZE),
                ("max_serialized_size", _MAX_SIZE), ("key_callbacks", ctypes.c_void_p)]


class _TypeSupport(ctypes.Structure):
    _fields_ = [("typesupport_identifier", ctypes.c_char_p), ("data", ctypes.c_void_p), ("func", ctypes.c_void_p),
                ("get_type_hash_func", _GETTER), ("get_type_description_func", _GETTER),
                ("get_type_description_sources_func", _GETTER)]


def _string(text: str, keep: list) -> _String:
    raw = ctypes.create_string_buffer(text.encode())
    keep.append(raw)
    return _String(ctypes.cast(raw, ctypes.c_char_p), len(text), len(text) + 1)


def _array(item, values: list, keep: list):
    seq_type = dict(_Individual._fields_)["fields"] if item is _Field else dict(
        _TypeDescription._fields_)["referenced_type_descriptions"]
    array = (item * max(len(values), 1))(*values)
    keep.append(array)
    return seq_type(ctypes.cast(array, ctypes.POINTER(item)), len(values), len(values))


def _individual(desc: dict, keep: list) -> _Individual:
    fields = [_Field(_string(f["name"], keep), _FieldType(
        f["type"]["type_id"], f["type"]["capacity"], f["type"]["string_capacity"],
        _string(f["type"]["nested_type_name"], keep)), _string("", keep)) for f in desc["fields"]]
    return _Individual(_string(desc["type_name"], keep), _array(_Field, fields, keep))


def _never_called(*_args) -> bool:
    return False


def _unbounded_size(bounds_info) -> int:
    bounds_info[0] = b"\x00"  # ROSIDL_TYPESUPPORT_FASTRTPS_UNBOUNDED_TYPE
    return 0


class _RawMeta(type):
    """Metaclass of a serialized-only message class; rclpy reads ``_TYPE_SUPPORT`` from here."""

    @classmethod
    def __import_type_support__(cls) -> None:
        """Already made at class creation."""


@functools.cache
def raw_message_class(typename: str) -> type:
    """A message class for ``typename`` (``pkg/msg/Name``) that rclpy publishers and raw
    subscriptions accept; its instances are never made: publish CDR ``bytes``."""
    import rclpy  # noqa: F401 - puts the ROS libraries on the loader's path first

    package, _, name = typename.split("/")
    keep: list = []
    description = type_description(typename)
    c_description = _TypeDescription(
        _individual(description["type_description"], keep),
        _array(_Individual, [_individual(d, keep) for d in description["referenced_type_descriptions"]], keep))
    digest = bytes.fromhex(hash_of(typename).removeprefix("RIHS01_"))
    c_hash = _Hash(1, (ctypes.c_uint8 * 32)(*digest))
    sources = _TypeSourceSeq(None, 0, 0)
    callbacks = _Callbacks(f"{package}::msg".encode(), name.encode(), _CDR(_never_called), _CDR(_never_called),
                           _SIZE(lambda _msg: 0), _MAX_SIZE(_unbounded_size), None)
    runtime = ctypes.CDLL("librosidl_runtime_c.so")
    getters = [_GETTER(lambda _ts, obj=obj: ctypes.addressof(obj)) for obj in (c_hash, c_description, sources)]
    support = _TypeSupport(b"rosidl_typesupport_fastrtps_c", ctypes.addressof(callbacks),
                           ctypes.cast(runtime.get_message_typesupport_handle_function, ctypes.c_void_p).value,
                           *getters)
    capsule_new = ctypes.pythonapi.PyCapsule_New
    capsule_new.restype, capsule_new.argtypes = ctypes.py_object, [ctypes.c_void_p, ctypes.c_char_p, ctypes.c_void_p]
    capsule = capsule_new(ctypes.addressof(support), None, None)
    meta = type(f"Metaclass_{name}", (_RawMeta,), {
        "_TYPE_SUPPORT": capsule, "_CREATE_ROS_MESSAGE": capsule, "_CONVERT_FROM_PY": capsule,
        "_CONVERT_TO_PY": capsule, "_DESTROY_ROS_MESSAGE": capsule,
        # the C structs live as long as the class (forever: the function is cached)
        "_keep": (keep, c_description, c_hash, sources, callbacks, getters, support, runtime)})
    return meta(name, (), {"__module__": f"{package}.msg", "__doc__": f"{typename}, serialized messages only"})


def clear_rcutils_error() -> None:
    """Forget the error rmw_fastrtps leaves set while it probes a raw type for typesupports it does
    not need (else rcutils prints "This error state is being overwritten" at the next error)."""
    ctypes.CDLL("librcutils.so").rcutils_reset_error()


__all__ = ["clear_rcutils_error", "hash_of", "raw_message_class", "type_description", "typestore"]
