"""``python -m experiments NAME [--quick] [--json] [--out DIR]``."""
import sys

from .cli import main

if __name__ == "__main__":
    sys.exit(main())
