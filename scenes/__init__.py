"""The shipped scenes (``*.toml``), installed with the package as ``orchestrator.scenes`` so that ``wingsim run
deploy_rigid`` finds them by name from any folder (``orchestrator.scene.shipped``); docs/scenes.md describes them."""
