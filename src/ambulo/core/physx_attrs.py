"""The attributes of PhysX's USD schema (``PhysxSchema``), as Isaac Sim's stages carry them.

Each applied API (``PhysxRigidBodyAPI`` ...) authors ``<namespace>:<name>`` attributes on its
prim, with the Sdf type and fallback value below (PhysX SDK 5 / Isaac Sim 4's
``physxSchema/generatedSchema.usda``; attributes that older releases had, such as
``physxMaterial:improvePatchFriction``, are kept so older scripts still author them). usd-core
has no PhysxSchema: ``ambulo.isaac.physx_schema`` authors these under ``ambulo run`` and
``ambulo.core.usd_physx`` honours the ones with a MuJoCo meaning when a stage is simulated.
"""

from __future__ import annotations

import math
from dataclasses import dataclass


@dataclass(frozen=True)
class PhysxAttr:
    name: str
    """The attribute's base name, e.g. ``linearDamping`` (``CreateLinearDampingAttr``)."""
    type_name: str
    """Sdf value type name: ``float``, ``int``, ``uint``, ``uint64``, ``bool``, ``token``, ``vector3f``."""
    fallback: object
    """The schema's fallback value: what PhysX uses when the attribute is not authored."""
    uniform: bool = False

    @property
    def method(self) -> str:
        """The ``Create<Method>Attr`` / ``Get<Method>Attr`` part of the accessor names."""
        return self.name[0].upper() + self.name[1:]


@dataclass(frozen=True)
class PhysxApi:
    name: str
    """The applied schema's name, e.g. ``PhysxRigidBodyAPI`` (its ``apiSchemas`` entry)."""
    namespace: str
    """The attributes' namespace, e.g. ``physxRigidBody``."""
    attributes: tuple[PhysxAttr, ...]
    relationships: tuple[str, ...] = ()
    multiple_apply: bool = False
    """A multiple-apply API (``PhysxLimitAPI``): ``Apply(prim, "rotX")`` authors
    ``physxLimit:rotX:<name>`` and the apiSchemas entry ``PhysxLimitAPI:rotX``."""

    def property_name(self, name: str, instance: str | None = None) -> str:
        return f"{self.namespace}:{instance}:{name}" if self.multiple_apply else f"{self.namespace}:{name}"


def _api(name: str, namespace: str, table: str, relationships: tuple[str, ...] = (),
         multiple_apply: bool = False) -> PhysxApi:
    """A ``PhysxApi`` from lines ``[uniform] <type> <name> <fallback>``."""
    attributes = []
    for line in table.strip().splitlines():
        words = line.split()
        uniform = words[0] == "uniform"
        type_name, attr, *fallback = words[1:] if uniform else words
        attributes.append(PhysxAttr(attr, type_name, _parse(type_name, " ".join(fallback)), uniform))
    return PhysxApi(name, namespace, tuple(attributes), relationships, multiple_apply)


def _parse(type_name: str, text: str):
    if type_name == "bool":
        return text == "1"
    if type_name in ("int", "uint", "uint64"):
        return int(text)
    if type_name == "float":
        return float(text)
    if type_name == "vector3f":
        return (0.0, 0.0, 0.0)
    return text.strip('"')


APIS: dict[str, PhysxApi] = {api.name: api for api in (
    _api("PhysxRigidBodyAPI", "physxRigidBody", """
        float linearDamping 0
        float angularDamping 0.05
        float maxLinearVelocity inf
        float maxAngularVelocity 5729.58
        float sleepThreshold 0.00005
        float stabilizationThreshold 0.00001
        float maxDepenetrationVelocity 3
        float maxContactImpulse inf
        int solverPositionIterationCount 16
        int solverVelocityIterationCount 1
        bool enableCCD 0
        bool enableSpeculativeCCD 0
        bool retainAccelerations 0
        bool enableGyroscopicForces 1
        bool disableGravity 0
        int lockedPosAxis 0
        int lockedRotAxis 0
        float cfmScale 0.025
        float contactSlopCoefficient 0
        bool solveContact 1"""),
    _api("PhysxArticulationAPI", "physxArticulation", """
        bool articulationEnabled 1
        bool enabledSelfCollisions 1
        int solverPositionIterationCount 32
        int solverVelocityIterationCount 1
        float sleepThreshold 0.00005
        float stabilizationThreshold 0.00001"""),
    _api("PhysxCollisionAPI", "physxCollision", """
        float contactOffset -inf
        float restOffset -inf
        float torsionalPatchRadius 0
        float minTorsionalPatchRadius 0"""),
    _api("PhysxJointAPI", "physxJoint", """
        float armature 0
        bool enableProjection 0
        float jointFriction 0
        float maxJointVelocity 1000000"""),
    _api("PhysxMaterialAPI", "physxMaterial", """
        uniform token frictionCombineMode average
        uniform token restitutionCombineMode average
        uniform token dampingCombineMode average
        bool improvePatchFriction 1
        float compliantContactStiffness 0
        float compliantContactDamping 0
        bool compliantContactAccelerationSpring 0"""),
    _api("PhysxContactReportAPI", "physxContactReport", """
        float threshold 1""", relationships=("reportPairs",)),
    _api("PhysxSceneAPI", "physxScene", """
        uint timeStepsPerSecond 60
        uniform uint minPositionIterationCount 1
        uniform uint maxPositionIterationCount 255
        uniform uint minVelocityIterationCount 0
        uniform uint maxVelocityIterationCount 255
        uint minIterationCount 0
        uint maxIterationCount 255
        float bounceThreshold 0.2
        float frictionOffsetThreshold 0.04
        float frictionCorrelationDistance 0.025
        float maxBiasCoefficient inf
        uniform token collisionSystem PCM
        uniform token solverType TGS
        uniform token broadphaseType GPU
        uniform token frictionType patch
        uniform token updateType Synchronous
        bool enableCCD 0
        bool enableStabilization 0
        bool enableGPUDynamics 1
        bool enableEnhancedDeterminism 0
        bool enableExternalForcesEveryIteration 0
        bool enableResidualReporting 0
        bool enableSceneQuerySupport 1
        bool invertCollisionGroupFilter 0
        bool reportKinematicKinematicPairs 0
        bool reportKinematicStaticPairs 0
        uint64 gpuTempBufferCapacity 16777216
        uint gpuMaxRigidContactCount 524288
        uint gpuMaxRigidPatchCount 81920
        uint gpuHeapCapacity 67108864
        uint gpuFoundLostPairsCapacity 262144
        uint gpuFoundLostAggregatePairsCapacity 1024
        uint gpuTotalAggregatePairsCapacity 1024
        uint gpuMaxSoftBodyContacts 1048576
        uint gpuMaxDeformableSurfaceContacts 1048576
        uint gpuMaxParticleContacts 1048576
        uint gpuMaxHairContacts 1048576
        uint gpuMaxNumPartitions 8
        uint gpuCollisionStackSize 67108864"""),
    _api("PhysxLimitAPI", "physxLimit", """
        float restitution 0
        float bounceThreshold 0
        float stiffness 0
        float damping 0
        float contactDistance 0""", multiple_apply=True),
    # named so scripts that author them run; MuJoCo has no triggers or character controllers
    _api("PhysxTriggerAPI", "physxTrigger", """
        uniform token enterScriptType scriptFile
        uniform token leaveScriptType scriptFile
        uniform token onEnterScript ""
        uniform token onLeaveScript ""
        """),
    _api("PhysxCharacterControllerAPI", "physxCharacterController", """
        uniform token climbingMode easy
        float contactOffset 0.1
        float invisibleWallHeight 0
        float maxJumpHeight 0
        vector3f moveTarget 0
        uniform token nonWalkableMode preventClimbing
        float scaleCoeff 0.8
        float slopeLimit 0.3
        float stepOffset 0.5
        uniform token upAxis Z
        float volumeGrowth 1.5"""),
)}
"""Applied API name -> its attributes."""

NAMED_ONLY = ("PhysxTriggerAPI", "PhysxCharacterControllerAPI")
"""APIs that author their attributes but have no counterpart in MuJoCo at all."""


def fallback(attribute: str):
    """The schema fallback of ``attribute`` (``physxRigidBody:linearDamping``), or None if unknown."""
    namespace, _, name = attribute.partition(":")
    for api in APIS.values():
        if api.namespace == namespace:
            name = name.rsplit(":", 1)[-1] if api.multiple_apply else name
            return next((a.fallback for a in api.attributes if a.name == name), None)
    return None


def is_fallback(attribute: str, value) -> bool:
    """Whether ``value`` is the schema's fallback, so authoring it changes nothing in PhysX."""
    default = fallback(attribute)
    if default is None or value is None:
        return False
    if isinstance(default, float):
        try:
            return math.isclose(float(value), default, rel_tol=1e-6) or float(value) == default
        except (TypeError, ValueError):
            return False
    if isinstance(default, tuple):
        return tuple(value) == default
    return value == default


__all__ = ["APIS", "NAMED_ONLY", "PhysxApi", "PhysxAttr", "fallback", "is_fallback"]
