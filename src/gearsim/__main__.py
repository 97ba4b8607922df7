"""``python -m gearsim`` runs the CLI."""

from gearsim.cli.main import main

raise SystemExit(main())
