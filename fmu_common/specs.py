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
    communication step) and the strip theory's span_correction."""

    model: AeroModel
    chordwise_panels: int
    spanwise_panels: int
    wake_length: float
    step: float | None
    span_correction: str


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
    reference line times the flap curvature (Otsuka et al. 2022, Sec. 5)."""

    key: str
    name: str
    body: str
    span: float
    surface_distance: float


@dataclass(frozen=True)
class StructureUnitSpec:
    """What the structure unit reads: time, coupling, the structure table, probes and strain gauges."""

    time: TimeSpec
    coupling: CouplingSpec
    structure: StructureSpec
    probes: tuple[ProbeSpec, ...]
    strain_gauges: tuple[StrainGaugeSpec, ...]
    parameters: tuple[tuple[str, tuple[float, str, str]], ...]   # (name, (default, unit, description)) of the
    # structure table's tunable keys (fmu_common.scene_schema.tunable_parameters), the unit's FMI parameters

    @classmethod
    def from_scene(cls, scene: dict) -> "StructureUnitSpec":
        """The structure unit's spec of a resolved scene.

        Args:
            scene: the resolved scene.
        """
        probes = tuple(ProbeSpec(f"probes.{item_label(i, p)}", p["name"], p["body"], p["span"], p["chord"])
                       for i, p in enumerate(scene["probes"]))
        gauges = tuple(StrainGaugeSpec(f"strain_gauges.{item_label(i, g)}", g["name"], g["body"], g["span"],
                                       g["surface_distance"]) for i, g in enumerate(scene["strain_gauges"]))
        return cls(TimeSpec(scene["time"]["stop"]), CouplingSpec(scene["coupling"]["step"]),
                   StructureSpec.from_scene(scene), probes, gauges,
                   tuple(tunable_parameters(scene, "structure").items()))


@dataclass(frozen=True)
class AeroUnitSpec:
    """What the aero unit reads: time, coupling, flow, the aero table, the structure table (for the topology) and
    the scene's name (for its messages)."""

    time: TimeSpec
    coupling: CouplingSpec
    flow: FlowSpec
    aero: AeroSpec
    structure: StructureSpec
    parameters: tuple[tuple[str, tuple[float, str, str]], ...]   # (name, (default, unit, description)) of the
    # flow table's tunable keys (fmu_common.scene_schema.tunable_parameters), the unit's FMI parameters
    name: str = ""      # the scene's name, to say which unit refused a structure (aero_fmu.pairing)

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
                            aero["wake_length"], aero["step"], aero["span_correction"]),
                   StructureSpec.from_scene(scene), tuple(tunable_parameters(scene, "flow").items()),
                   str(scene.get("name", "")))
