"""python3 -m exodaq: print the exodaq messages that arrive (--help)."""
import sys

from .client import main

sys.exit(main())
