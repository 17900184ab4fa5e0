"""The size of a scene's structural equations, for ``summary.json``: how many coordinates the structure unit
integrates and how many constraint rows it solves with them.

The counts are derived from the resolved scene by the construction the structure unit makes (its topology and
its fidelity's model, ``structure_fmu.fidelities``), without stepping it, so they are the same for every
backend. The model is built once more for this, in the master; nothing is integrated.
"""
from __future__ import annotations

from typing import Any


def structure_counts(scene: dict) -> dict[str, Any]:
    """The structure's equation counts of a resolved scene.

    Returns:
        {"fidelity": structure.fidelity, "coordinates": n_q, the generalized coordinates q the integrator
        advances (after the coordinates shared by pins and those prescribed are eliminated, and the point of a
        node on a fixed slider line or plane is replaced by its travel along it, E = T q + P p);
        "exchanged_coordinates": n, the coordinates E the unit exchanges (9 per node: r, r_x, r_y, Otsuka et
        al. 2019, Eq. 3; the strain-based fidelity's too); "constraint_rows": m, the rows of Phi(q, t) = 0 the
        integrator solves (internal, joint and slider rows, the redundant rows of planar rigid loops left out)}.
        With m = 0 the equations of motion are an ODE on q.

    Raises:
        SceneError naming the key when the structure cannot be built (as the structure unit would).
    """
    from fmu_common.specs import StructureUnitSpec    # lazy: the physics packages are needed only here
    from structure_fmu.fidelities import model_class
    from structure_fmu.topology import StructureTopology

    structure = StructureUnitSpec.from_scene(scene).structure
    topology = StructureTopology.from_spec(structure)
    model = model_class(structure.fidelity)(topology, structure.gravity)
    return {"fidelity": structure.fidelity.name, "coordinates": len(model.initial_coordinates()),
            "exchanged_coordinates": topology.n_coordinates, "constraint_rows": model.constraint_count}
