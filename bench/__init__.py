"""levelset-bench: the command line, grid runner, metrics and report rendering."""

__version__ = "0.1.0"
