"""Subcommands of the ``gearsim`` CLI (one module each; see :mod:`gearsim.cli.main`)."""
