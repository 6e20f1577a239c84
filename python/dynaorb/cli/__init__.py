"""The `dynaorb` command line."""
from dynaorb.cli.main import main

__all__ = ["main"]
