"""``python -m rlsfilt``: the command line of :mod:`rlsfilt.cli`."""

import sys

from .cli import main

__all__ = ["main"]

if __name__ == "__main__":
    sys.exit(main())
