"""Scene stage: a TOML scene resolved into a complete, validated scene before anything runs.

- ``load``       read a TOML scene, apply overrides and shorthands, resolve it against the schema
                 (``fmu_common.scene_schema``) and check what the schema alone cannot
- ``overrides``  ``--set KEY=VALUE`` on a raw scene
- ``shipped``    the scenes shipped with the package (``orchestrator.scenes``): found by name, listed, copied
- ``plausibility`` the plausible ranges of flow values, noted (not refused) before a run
- ``columns``    the fixed columns of ``timeseries.csv``, which a scene's own names must not take
- ``docs``       docs/scenes.md, generated from the schema and ``templates/scenes.md``
"""
