#!/usr/bin/env python3
"""Compatibility: the former exodaq_lcm module, now a front for the exodaq package.

New code imports the package (docs/messages.md, *Python*):

    import exodaq
    with exodaq.Subscriber(prefix="") as sub: ...

This module keeps older scripts working: Receiver(url, channels=None,
prefix=None), decode(data), fields(msg), import_types(path), BASE_CHANNELS,
DEFAULT_URL, and `python3 exodaq_lcm.py [--types DIR] ...` (as `python3 -m
exodaq`). It is installed next to the package (pip, the .deb) and also works
from tools/python in a source tree: the package is then taken from
import_types(path), $EXODAQ_LCMTYPES_PYTHONPATH or build/python, the first
that holds it.
"""

import importlib
import os
import sys

_FROM_PACKAGE = {"DEFAULT_URL": "udpm", "MAGIC_SHORT": "udpm", "MAGIC_LONG": "udpm",
                 "parse_url": "udpm", "BASE_CHANNELS": "names", "fields": "client"}


def import_types(path=None):
    """Imports the exodaq package and returns it; `path` (or
    $EXODAQ_LCMTYPES_PYTHONPATH, or build/python of this source tree) is put
    first on sys.path when it holds the package and none is imported yet."""
    if "exodaq" not in sys.modules:
        here = os.path.dirname(os.path.abspath(__file__))
        for c in (path, os.environ.get("EXODAQ_LCMTYPES_PYTHONPATH"),
                  os.path.join(here, "..", "..", "build", "python")):
            if c and os.path.isfile(os.path.join(c, "exodaq", "client.py")):
                c = os.path.abspath(c)
                if c not in sys.path:
                    sys.path.insert(0, c)
                break
    return importlib.import_module("exodaq")


def __getattr__(name):  # the constants, from the package on first use
    if name in _FROM_PACKAGE:
        import_types()
        return getattr(importlib.import_module("exodaq." + _FROM_PACKAGE[name]), name)
    raise AttributeError("module %r has no attribute %r" % (__name__, name))


def Receiver(url=None, channels=None, prefix=None, recv_buf_size=None):
    """exodaq.Receiver; with channels=None and a prefix, every exodaq channel of that rig."""
    exodaq = import_types()
    if channels is None and prefix is not None:
        channels = [prefix + c for c in exodaq.BASE_CHANNELS]
    return exodaq.Receiver(url or exodaq.DEFAULT_URL, channels=channels,
                           recv_buf_size=recv_buf_size)


def decode(data, types=None):
    """exodaq.decode: the message by fingerprint, None for a foreign type."""
    return import_types().decode(data)


def main(argv=None):
    argv = list(sys.argv[1:] if argv is None else argv)
    path = None
    if "--types" in argv:  # the former option: where the package is
        i = argv.index("--types")
        path = argv[i + 1] if i + 1 < len(argv) else None
        del argv[i:i + 2]
    return import_types(path).main(argv)


if __name__ == "__main__":
    sys.exit(main())
