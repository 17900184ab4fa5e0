"""``python -m orchestrator`` is the ``wingsim`` command."""

from orchestrator.cli import main

raise SystemExit(main())
