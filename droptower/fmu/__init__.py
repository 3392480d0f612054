"""A coupling as an FMI 2.0 co-simulation FMU (``droptower export-fmu``): :func:`build_fmu`
writes the FMU, :mod:`.slave` is the model inside it (built with pythonfmu; the importing tool
needs a Python with pythonfmu's runtime and this package)."""
from droptower.fmu.build import build_fmu

__all__ = ["build_fmu"]
