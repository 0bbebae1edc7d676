"""Exports, used alike by the editor and the command line.

- :mod:`.loaded`: a document loaded onto one GL context (what exports read).
- :mod:`.window`: window exports (a rectangle or a toroidal tile, every map,
  8/16/32 bits, magnified or in a lattice's original geometry).
- :mod:`.streamed`: huge exports in bounded memory, resumable: tile sets,
  BigTIFF, Zarr (:mod:`.zarr_store`), rendered here or by :mod:`.workers`
  (process pool, Dask).
- :mod:`.jobs`: streamed exports run from the editor, and their estimates.
- :mod:`.formats`: tile encodings, UDIM names, the coordinate map.
"""
from .errors import ExportCancelled, ExportFailed, ExportInterrupted
from .formats import (
    check_zarr_output,
    decode_coords,
    encode_coords,
    read_tiles,
    udim_name,
)
from .streamed import FORMATS, MAX_SIDE, TILE_SIZES, TiledExport

__all__ = [
    "ExportCancelled", "ExportFailed", "ExportInterrupted", "check_zarr_output", "decode_coords",
    "encode_coords", "read_tiles", "udim_name", "FORMATS", "MAX_SIDE", "TILE_SIZES", "TiledExport",
]
