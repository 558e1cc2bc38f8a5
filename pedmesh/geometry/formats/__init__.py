"""Geometry file formats: native JSON, GeoJSON, DXF and SVG, registered by suffix."""

from . import dxf, geojson, native, svg  # noqa: F401  (registration side effects)
from ...errors import UnsupportedFormatError
from ._registry import RoomFormat, format_for, formats, register_format

__all__ = ["RoomFormat", "format_for", "formats", "register_format"]
