"""The version of rlsfilt (one home: setup.cfg, the package and the JSON results read it)."""

__version__ = "0.1.0"
