"""Subcommands of the ``carmkin`` CLI: one module each, discovered by :mod:`carmkin.cli`."""
