"""wingsim's Python API, for scripts and notebooks (docs/api.md):

    import wingsim

    scene = wingsim.load_scene("deploy_rigid")          # a shipped scene by name, or a scene file
    scene.set("time.stop", 0.5)                          # --set time.stop=0.5, checked now
    result = wingsim.run(scene, overrides={"flow.speed": 10}, backend="direct")
    result.deployment_time_s                             # summary.json's fields as attributes
    result.timeseries["tip_z"], result.units["tip_z"]    # samples (numpy structured array) and "m"
    sweep = wingsim.sweep(scene, grid={"flow.speed": [0, 10]})
    sweep.column("deployment_time_s")

A thin layer over the master (``orchestrator``): it loads scenes as ``wingsim run`` does, runs them with the
same code, and reads results back from the files a run writes (``summary.json``, ``timeseries.csv``).

- ``scene``    ``Scene``, ``load_scene``, ``shipped_scenes``: scene files and shipped scenes with overrides
- ``result``   ``Result``, ``load_result``: a run's summary as attributes, its samples with units
- ``running``  ``run``, ``sweep``, ``SweepResult``: one run or a grid of runs
"""

from fmu_common.errors import SceneError
from wingsim.result import Result, load_result
from wingsim.running import SweepResult, run, sweep
from wingsim.scene import Scene, load_scene, shipped_scenes

__all__ = ["Scene", "SceneError", "Result", "SweepResult", "load_scene", "load_result", "run", "shipped_scenes",
           "sweep", "scene", "result", "running"]   # the modules too: the API reference (pdoc) has a page for each
