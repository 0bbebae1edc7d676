"""Documents and projects, without GL or imgui: the document model
(:mod:`.document`), the ``.itex`` file format (:mod:`.format`), undo/redo
(:mod:`.history`), autosave (:mod:`.autosave`) and what a document is made of
for the engine (:mod:`.realize`: its exemplar, analysis settings, material).

The command line, the export workers and the editor all use it; it uses only
the engine's CPU side.
"""
from .autosave import Autosave, Recoverable, autosave_path, state_dir
from .document import (
    DISPLAY_MODES,
    GEOMETRIES,
    MAGNIFY_FILTERS,
    MAX_ZOOM,
    MIN_ZOOM,
    Display,
    Document,
    ExemplarSource,
    Project,
    ProjectError,
    View,
)
from .format import (
    EMBED_LIMIT,
    FORMAT,
    MAX_PROJECT_BYTES,
    PROJECT_SUFFIX,
    VERSION,
    ExemplarOutside,
    fitted_project_json,
    is_project_file,
    load_project,
    parse_project_json,
    project_from_json,
    project_save_path,
    project_to_json,
    save_project,
)
from .history import History

__all__ = [
    "Autosave", "Recoverable", "autosave_path", "state_dir", "DISPLAY_MODES", "GEOMETRIES", "MAGNIFY_FILTERS",
    "MAX_ZOOM", "MIN_ZOOM", "Display", "Document", "ExemplarSource", "Project", "ProjectError", "View",
    "EMBED_LIMIT", "FORMAT", "MAX_PROJECT_BYTES", "PROJECT_SUFFIX", "VERSION", "ExemplarOutside",
    "fitted_project_json", "is_project_file", "load_project", "parse_project_json", "project_from_json",
    "project_save_path", "project_to_json", "save_project", "History",
]
