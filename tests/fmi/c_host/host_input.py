"""Write the input file of the C host (fmi2_host.c, its header comment) for the coupled FMUs of one scene.

Usage: python tests/fmi/c_host/host_input.py FMU_FOLDER UNZIP_FOLDER > input.txt

Unzips FMU_FOLDER/structure.fmu and FMU_FOLDER/aero.fmu (as `wingsim build SCENE` writes them) into
UNZIP_FOLDER/structure/ and UNZIP_FOLDER/aero/ and prints the input that couples them as wingsim's master does
(Gauss-Seidel, structure first; every input from the other unit's output of the same name; every Real output a
column) over the time span and communication step of the scene embedded in the FMUs.
"""
import sys
import zipfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))   # tests/: the hosts' shared helpers

from fmi_hosts import coupled_units, host_input  # noqa: E402
from orchestrator.build.fmus import embedded_scene  # noqa: E402
from orchestrator.run.master import communication_times  # noqa: E402


def main(fmu_folder: Path, unzip_folder: Path) -> str:
    unzipped = {}
    for kind in ("structure", "aero"):
        with zipfile.ZipFile(fmu_folder / f"{kind}.fmu") as fmu:
            fmu.extractall(unzip_folder / kind)
        unzipped[kind] = (unzip_folder / kind).resolve()
    scene = embedded_scene(fmu_folder / "structure.fmu")
    step, stop = scene["coupling"]["step"], scene["time"]["stop"]
    return host_input(coupled_units(unzipped), len(communication_times(stop, step)) - 1, step, stop)


if __name__ == "__main__":
    if len(sys.argv) != 3:
        sys.exit(__doc__.split("\n\n")[1])
    print(main(Path(sys.argv[1]), Path(sys.argv[2])), end="")
