"""The strain-based structure FMU exchanges what the ANCF units do: it couples with an aero FMU built for the ANCF
scene (same node slots, same topology hash), and the coupled run equals the in-process one."""
import shutil

import numpy as np

from fmu_common.topology import Topology
from fmu_common.wing_spec import StructureSpec
from orchestrator.run.master import run_scene
from orchestrator.scene.load import load_scene
from repository import SCENES

STRAIN = ["structure.fidelity=strain-based", "time.stop=0.02"]


def test_a_strain_based_structure_fmu_drives_the_aero_fmu_of_the_ancf_scene(built_fmus, tmp_path):
    ancf = load_scene(SCENES / "deploy_flexible.toml", ["time.stop=0.02"])
    strain = load_scene(SCENES / "deploy_flexible.toml", STRAIN)
    topology_hash = lambda scene: Topology.from_spec(StructureSpec.from_scene(scene)).topology_hash
    assert topology_hash(ancf) == topology_hash(strain)
    shutil.copy(built_fmus("deploy_flexible", *STRAIN) / "structure.fmu", tmp_path / "structure.fmu")
    shutil.copy(built_fmus("deploy_flexible", "time.stop=0.02") / "aero.fmu", tmp_path / "aero.fmu")
    mixed = run_scene(strain, backend="fmu", fmu_dir=tmp_path)
    direct = run_scene(strain, backend="direct")
    assert mixed.status == direct.status == "ok", mixed.message
    np.testing.assert_allclose(mixed.series.table(), direct.series.table(), rtol=1e-10, atol=1e-12)
    # and the strain-based wing is not the ANCF one: the fidelity changed the motion
    ancf_run = run_scene(ancf, backend="direct")
    assert np.abs(ancf_run.series.column("tip_y") - direct.series.column("tip_y")).max() > 1e-7
