"""What each unit reads of a resolved scene, as frozen, typed specs: `StructureUnitSpec` and `AeroUnitSpec`.

A resolved scene (fmu_common.scene_schema.resolve_scene; the `scene.json` an FMU embeds) is converted once, where
a unit starts (`from_scene`); the solvers, topologies, models and sensors take these specs and never read the
dict. SI units (s, m, kg/m^3, m/s); vectors are tuples of 3 floats in the global frame. The structure table is
`fmu_common.wing_spec.StructureSpec`, which both units read: the aero unit builds the same topology.
"""
from __future__ import annotations

from dataclasses import dataclass

from .choices import AeroModel, aero_model
from .scene_schema import tunable_parameters
from .schema import item_label
from .wing_spec import StructureSpec, Vector


@dataclass(frozen=True)
class SceneSpec:
    """The scene's `name`: with the unit's choices it names an FMU in its model description
    (`StructureUnitSpec.fmi_model_name`, `AeroUnitSpec.fmi_model_name`). The scene file's free-text description
    is left out: an FMU built with ``--set`` overrides (another aero model, another speed) would quote a text
    that describes another variant."""

    name: str

    @classmethod
    def from_scene(cls, scene: dict) -> "SceneSpec":
        """The name of a resolved scene.

        Args:
            scene: the resolved scene.
        """
        return cls(scene["name"])

    def described(self, unit: str) -> str:
        """'<unit>. Scene <name>'.

        Args:
            unit: what the unit is and how it is configured, e.g. "Structure unit (wingsim): rigid fidelity".

        Returns:
            the text of an FMU's description attribute.
        """
        return f"{unit}. Scene {self.name}"


@dataclass(frozen=True)
class TimeSpec:
    """`time`: the end time stop (s)."""

    stop: float


@dataclass(frozen=True)
class CouplingSpec:
    """`coupling` as a unit sees it: the communication step (s), the default experiment's step size."""

    step: float


@dataclass(frozen=True)
class FlowSpec:
    """`flow`: free-stream speed (m/s), air density (kg/m^3) and direction (-, global frame, not normalized: the
    air velocity is speed x direction / |direction|)."""

    speed: float
    density: float
    direction: Vector


@dataclass(frozen=True)
class AeroSpec:
    """`aero`: the model (its traits, fmu_common.choices: strip, uvlm-flat, uvlm-prescribed, uvlm-free; none
    builds no aero unit; aero_fmu.models builds the others), M chordwise_panels and N spanwise_panels per body,
    the wake truncation wake_length (chords; inf allowed), the internal aero step (s; None: one per
    communication step), the strip theory's span_correction, and the free wake's far-field sum (wake_far_field,
    treecode or exact, with the treecode's opening parameter wake_opening)."""

    model: AeroModel
    chordwise_panels: int
    spanwise_panels: int
    wake_length: float
    step: float | None
    span_correction: str
    wake_far_field: str
    wake_opening: float


@dataclass(frozen=True)
class ProbeSpec:
    """A probe: the material point of `body` at `span` (m from its root) and `chord` (fraction of the chord from
    the leading edge) whose position, velocity and acceleration the structure unit outputs as `<name>_x` ..."""

    key: str
    name: str
    body: str
    span: float
    chord: float


@dataclass(frozen=True)
class StrainGaugeSpec:
    """A strain gauge: the surface strain at `span` (m from the root of `body`), surface_distance (m) from the
    reference line times the flap curvature (Otsuka et al. 2022, Sec. 5): the model's own ("model") or that of
    the cubic interpolation of the nodal vectors ("cubic")."""

    key: str
    name: str
    body: str
    span: float
    surface_distance: float
    curvature: str = "model"


@dataclass(frozen=True)
class StructureUnitSpec:
    """What the structure unit reads: time, coupling, the structure table, probes and strain gauges, and the
    scene's name (which names its FMU)."""

    time: TimeSpec
    coupling: CouplingSpec
    structure: StructureSpec
    probes: tuple[ProbeSpec, ...]
    strain_gauges: tuple[StrainGaugeSpec, ...]
    parameters: tuple[tuple[str, tuple[float, str, str]], ...]   # (name, (default, unit, description)) of the
    # structure table's tunable keys (fmu_common.scene_schema.tunable_parameters), the unit's FMI parameters
    scene: SceneSpec

    @classmethod
    def from_scene(cls, scene: dict) -> "StructureUnitSpec":
        """The structure unit's spec of a resolved scene.

        Args:
            scene: the resolved scene.
        """
        probes = tuple(ProbeSpec(f"probes.{item_label(i, p)}", p["name"], p["body"], p["span"], p["chord"])
                       for i, p in enumerate(scene["probes"]))
        gauges = tuple(StrainGaugeSpec(f"strain_gauges.{item_label(i, g)}", g["name"], g["body"], g["span"],
                                       g["surface_distance"], g["curvature"])
                       for i, g in enumerate(scene["strain_gauges"]))
        return cls(TimeSpec(scene["time"]["stop"]), CouplingSpec(scene["coupling"]["step"]),
                   StructureSpec.from_scene(scene), probes, gauges,
                   tuple(tunable_parameters(scene, "structure").items()), SceneSpec.from_scene(scene))

    def fmi_model_name(self) -> str:
        """The FMU's modelName, '<scene> structure (<fidelity>)', e.g. 'deploy_rigid structure (rigid)'.

        The modelIdentifier (the binary's name) stays the slave's `model_name`, "structure".

        Returns:
            the modelName attribute of the model description.
        """
        return f"{self.scene.name} structure ({self.structure.fidelity.name})"

    def fmi_description(self) -> str:
        """The FMU's description: the unit, its fidelity, the integrator and internal step (none runs for a
        prescribed fidelity), the bodies and their elements, then the scene's name.

        Returns:
            the description attribute of the model description.
        """
        structure = self.structure
        if structure.fidelity.moved_by_law:
            solver = "every body moved rigidly by structure.motion, no integrator"
        else:
            solver = f"{structure.integrator} integrator (internal step {structure.step:g} s)"
        bodies = len(structure.bodies)
        elements = sum(body.elements for body in structure.bodies)
        return self.scene.described(
            f"Structure unit (wingsim): {structure.fidelity.name} fidelity, {solver}, {bodies} "
            f"bod{'y' if bodies == 1 else 'ies'} with {elements} element{'' if elements == 1 else 's'} in all")


@dataclass(frozen=True)
class AeroUnitSpec:
    """What the aero unit reads: time, coupling, flow, the aero table and the structure table (for the topology),
    and the scene's name (which names its FMU and its messages)."""

    time: TimeSpec
    coupling: CouplingSpec
    flow: FlowSpec
    aero: AeroSpec
    structure: StructureSpec
    parameters: tuple[tuple[str, tuple[float, str, str]], ...]   # (name, (default, unit, description)) of the
    # flow table's tunable keys (fmu_common.scene_schema.tunable_parameters), the unit's FMI parameters
    scene: SceneSpec

    @classmethod
    def from_scene(cls, scene: dict) -> "AeroUnitSpec":
        """The aero unit's spec of a resolved scene.

        Args:
            scene: the resolved scene.
        """
        flow, aero = scene["flow"], scene["aero"]
        return cls(TimeSpec(scene["time"]["stop"]), CouplingSpec(scene["coupling"]["step"]),
                   FlowSpec(flow["speed"], flow["density"], tuple(flow["direction"])),
                   AeroSpec(aero_model(aero["model"]), aero["chordwise_panels"], aero["spanwise_panels"],
                            aero["wake_length"], aero["step"], aero["span_correction"],
                            aero["wake_far_field"], aero["wake_opening"]),
                   StructureSpec.from_scene(scene), tuple(tunable_parameters(scene, "flow").items()),
                   SceneSpec.from_scene(scene))

    def fmi_model_name(self) -> str:
        """The FMU's modelName, '<scene> aero (<aero model>)', e.g. 'deploy_rigid aero (uvlm-flat)'.

        The modelIdentifier (the binary's name) stays the slave's `model_name`, "aero".

        Returns:
            the modelName attribute of the model description.
        """
        return f"{self.scene.name} aero ({self.aero.model.name})"

    def fmi_description(self) -> str:
        """The FMU's description: the unit, its aero model, the lattice (M x N vortex rings, chordwise x spanwise,
        per body, and the wake length; strip theory: N strips per body and the span correction), the structure's
        fidelity it reads, then the scene's name.

        Returns:
            the description attribute of the model description.
        """
        aero, bodies = self.aero, len(self.structure.bodies)
        per_body = "per body" if bodies == 1 else f"per body on {bodies} bodies"
        if aero.model.chordwise:
            lattice = (f"lattice of {aero.chordwise_panels} x {aero.spanwise_panels} panels (chordwise x spanwise) "
                       f"{per_body}, wake length {aero.wake_length:g} chords")
        else:
            lattice = f"{aero.spanwise_panels} strips {per_body}, span correction {aero.span_correction}"
        return self.scene.described(f"Aero unit (wingsim): {aero.model.name} aero model, {lattice}, for the "
                                    f"{self.structure.fidelity.name} structure")
