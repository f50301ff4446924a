"""Import open3d from a pip-only install.

open3d's Linux wheel links the system library libusb-1.0, which minimal
images lack. The ``libusb-package`` wheel ships that library; loading it
globally before open3d lets the dynamic linker resolve open3d's dependency
without any system package. ``import tipgeo`` never imports open3d; the scan
features call :func:`import_open3d` when they need it.
"""

from __future__ import annotations

import ctypes
import importlib
import sys
from typing import Any

from .errors import TipGeoError

__all__ = ["import_open3d"]


def import_open3d() -> Any:
    """Return the ``open3d`` module, preloading libusb-1.0 from the
    ``libusb-package`` wheel when the system lacks it."""
    if "open3d" in sys.modules:
        return sys.modules["open3d"]
    if sys.platform.startswith("linux"):
        try:
            ctypes.CDLL("libusb-1.0.so.0", mode=ctypes.RTLD_GLOBAL)
        except OSError:
            try:
                import libusb_package

                path = libusb_package.get_library_path()
                if path is not None:
                    ctypes.CDLL(str(path), mode=ctypes.RTLD_GLOBAL)
            except (ImportError, OSError):
                pass
    try:
        return importlib.import_module("open3d")
    except ImportError as e:
        raise TipGeoError(f"open3d cannot be imported ({e}); install it with "
                          "`pip install open3d libusb-package`") from None
