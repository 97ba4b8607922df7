"""``python -m gearsim`` runs the CLI."""

from .cli import main

raise SystemExit(main())
