"""The editor's documents: new, open (images, materials, projects, files
dropped on the window), save and save as, the questions asked before unsaved
edits are lost (replacing the document, quitting), autosave and recovery, and
the undo history every edit goes through.

``Documents`` is a part of the editor (``Editor.files``): it owns the
document's history, the project file it belongs to, the autosave, the
document being analyzed before it opens and the files dropped on the window.
The editor reads the document (``Editor.doc``) and makes edits
(``Editor.edit``) through it.
"""
from __future__ import annotations

import os
import random
import time
from dataclasses import replace

import numpy as np

from infinitex.engine.controls import MAX_LABELS, CanvasLabels
from infinitex.engine.material import MaterialError, assign_roles
from infinitex.engine.safeio import ReadError, printable
from infinitex.project import (
    PROJECT_SUFFIX,
    Autosave,
    Document,
    ExemplarOutside,
    ExemplarSource,
    History,
    Project,
    ProjectError,
    Recoverable,
    is_project_file,
    load_project,
    project_save_path,
    save_project,
)
from infinitex.project.realize import may_find_lattice

from .dialogs import PROJECT_FILTER

ASSETS = os.path.join(os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__)))), "assets")
# The first screen: a 256 px gravel bed with a few hundred stones, so that even
# at 25% no element repeats visibly (the 128 px gravel holds too few of them).
DEFAULT_EXEMPLAR = os.path.join(ASSETS, "gravel_bed.png")


def default_exemplar() -> str:
    """The image File > New and a bare start open: ``$INFINITEX_DEFAULT_EXEMPLAR``
    when set (an artist's own starting point; the GUI tests' small one), else
    the bundled gravel bed."""
    return os.environ.get("INFINITEX_DEFAULT_EXEMPLAR") or DEFAULT_EXEMPLAR


class Documents:
    """Opening, saving and replacing the document; its undo history."""

    def __init__(self, ed, autosave: Autosave | None = None) -> None:
        self.ed = ed
        self.history: History | None = None
        self.project_path: str | None = None
        self.autosave = autosave or Autosave(background=True)  # written beside the frames, never holding one up
        self.pending: tuple | None = None  # (kind, candidate Document, project or None, path) being analyzed
        self.pending_label = "Load exemplar"
        self.found_lattice = None  # the Detection that put the open image on its lattice (Exemplar panel)
        self._dropped: list[str] = []
        self.quit_requested = False
        self._close_requested = False

    # -- documents ----------------------------------------------------------

    @property
    def doc(self) -> Document | None:
        return self.history.current if self.history else None

    def project(self) -> Project:
        return Project(self.doc, self.ed.view, self.ed.display)

    def autosave_project(self) -> Project:
        """The project with the file it belongs to, so recovery restores its name."""
        return replace(self.project(), origin=os.path.abspath(self.project_path) if self.project_path else None)

    @property
    def title(self) -> str:
        """The window title: the document's name, * when it has unsaved edits."""
        if self.project_path:
            name = os.path.basename(self.project_path)
        elif self.doc is not None:
            name = f"untitled ({self.doc.exemplar.name})"
        else:
            name = "untitled"
        dirty = self.history is not None and self.history.dirty
        return f"{'*' if dirty else ''}{name} - Infinitex"

    def new_document(self) -> None:
        try:
            src = ExemplarSource.from_file(default_exemplar())
        except OSError as exc:
            self.ed.dialogs.message("Error", f"The default exemplar could not be read: {exc}")
            return
        self.begin_load("new", Document(src), None, None)

    def open_first(self) -> None:
        """The document the editor starts with (the command line's file, else a
        new one), then the questions about earlier sessions' unsaved work: one
        for each autosave whose editor is gone, oldest first (a running
        editor's autosave is not offered)."""
        recovered = self.autosave.pending_all() if self.ed.offer_recovery else []
        if self.ed.start_path:
            self.open_path(self.ed.start_path, first=True)
        else:
            self.new_document()
        for where, why in self.autosave.set_aside_all:
            self.ed.dialogs.message("Autosave set aside",
                                 f"The autosaved work of an earlier session could not be read ({why})\n"
                                 f"It was kept as {printable(where)}.")
        for i, rec in enumerate(recovered):
            self.ed.dialogs.ask("Recover unsaved work", recovery_question(rec, i, len(recovered)),
                             [("Recover", lambda rec=rec: self.confirm_discard(lambda: self._recover(rec))),
                              ("Discard", lambda rec=rec: self.autosave.discard(rec)),
                              ("Keep for later", None)])

    def open_path(self, path: str, first: bool = False, allow_outside=False, replace_exemplar: bool = False) -> None:
        """Open a project, or an image as a new document (untitled, default
        settings); with ``replace_exemplar`` the image replaces the exemplar of
        the open document instead (undoable; the Exemplar panel's button).
        One map of a material brings its siblings (named by the rule), and a
        folder is one material's maps.

        A project whose exemplar file lies outside the project's folder is
        opened only after the user confirms that file."""
        path = os.path.expanduser(path)
        try:
            if os.path.isfile(path) and is_project_file(path):
                proj = load_project(path, allow_outside=allow_outside)
                self.begin_load("project", proj.document, proj, path)
                return
        except ExemplarOutside as exc:
            allow = {exc.path}  # (exc itself is gone once the except block ends)
            self.ed.dialogs.ask("Exemplar outside the project's folder",
                             f"{exc}\nRead this file as the exemplar?",
                             [("Read it", lambda: self.open_path(path, first, allow_outside=allow,
                                                                 replace_exemplar=replace_exemplar)),
                              ("Cancel", lambda: self._open_failed(None, first))])
            return
        except ProjectError as exc:
            self._open_failed(str(exc), first)
            return
        except OSError as exc:
            self._open_failed(f"{printable(os.path.basename(path))} could not be read: {exc.strerror or exc}.", first)
            return
        self.open_paths([path], first, replace_exemplar)

    def open_paths(self, paths: list[str], first: bool = False, replace_exemplar: bool = False) -> None:
        """Open images as a document: one image, one map of a material (its
        siblings come along), a material's folder, or several maps at once
        (their roles from their names). All or nothing."""
        try:
            found = assign_roles([os.path.expanduser(p) for p in paths])
            maps = [(role, ExemplarSource.from_file(p)) for role, p in found.items()]
        except (MaterialError, ReadError) as exc:
            self._open_failed(str(exc), first)
            return
        except OSError as exc:
            self._open_failed(f"The maps could not be read: {exc.strerror or exc}.", first)
            return
        path = paths[0] if len(paths) == 1 else None
        base = self.doc if replace_exemplar and self.doc is not None else None
        if base is not None:
            # A lattice is marked in the old image's pixels: the new image starts without one.
            doc = replace(base, toroidal=None, lattice=None, weights=None)
            # In a palette the first exemplar is replaced (its label keeps its place, renamed).
            doc = doc.with_palette([tuple(maps), *doc.palette]) if doc.palette else doc.with_maps(maps)
            self.begin_load("exemplar", doc, None, path)
        else:
            self.begin_load("image", Document(maps[0][1]).with_maps(maps), None, path)

    def add_to_palette(self, paths: list[str]) -> None:
        """Add an image (or a material: one map brings its siblings) to the
        document's palette as a new label; one undo step, made once the
        palette is analyzed (a failure leaves the document as it was)."""
        doc = self.doc
        try:
            found = assign_roles([os.path.expanduser(p) for p in paths])
            entry = tuple((role, ExemplarSource.from_file(p)) for role, p in found.items())
        except (MaterialError, ReadError) as exc:
            self.ed.dialogs.message("Could not add to the palette", str(exc))
            return
        except OSError as exc:
            self.ed.dialogs.message("Could not add to the palette", f"The image could not be read: {exc.strerror or exc}.")
            return
        entries = doc.entries()
        if len(entries) >= MAX_LABELS:
            self.ed.dialogs.message("Could not add to the palette", f"A palette has at most {MAX_LABELS} exemplars.")
        elif sorted(r for r, _ in entry) != sorted(r for r, _ in entries[0]):
            self.ed.dialogs.message("Could not add to the palette",
                                 f"{printable(entry[0][1].name)} has the maps {', '.join(r for r, _ in entry)} "
                                 f"but the palette's exemplars have {', '.join(r for r, _ in entries[0])}; "
                                 "a palette's exemplars have the same maps.")
        else:
            self.begin_load("exemplar", doc.with_palette(entries + (entry,)), None, None, "Add to palette")

    def remove_from_palette(self, index: int) -> None:
        """Remove the palette's exemplar ``index`` (its label goes; canvas labels it had are erased)."""
        doc = self.doc
        if doc.labels is not None:  # the labels after it move down by one; its own become free
            lut = np.arange(MAX_LABELS + 1, dtype=np.uint8)
            lut[index + 1] = 0
            lut[index + 2:] -= 1
            canvas = CanvasLabels({k: lut[t] for k, t in doc.labels.canvas.tiles.items()})
            doc = replace(doc, labels=replace(doc.labels, canvas=canvas))
        doc = doc.with_palette([e for i, e in enumerate(doc.entries()) if i != index])
        self.begin_load("exemplar", doc, None, None, "Remove from palette")

    def _open_failed(self, msg: str | None, first: bool) -> None:
        if msg:
            self.ed.dialogs.message("Could not open", msg)
        if first and self.history is None:
            self.new_document()

    def begin_load(self, kind: str, doc: Document, proj: Project | None, path: str | None,
                    label: str = "Load exemplar") -> None:
        """Analyze ``doc`` and make it current only when that succeeds (a new
        document, or with kind "exemplar" an edit named ``label``)."""
        self.pending = (kind, doc, proj, path)
        self.pending_label = label
        # An image opened (or replacing the exemplar) is synthesized on the
        # lattice it shows, when one is found (the Exemplar panel says so).
        self.ed.session.load(doc, find_lattice=kind in ("image", "exemplar", "new"))

    def finish_load(self, job) -> None:
        kind, doc, proj, path = self.pending
        # The document shown: the image as given while its quick preview shows (a lattice found later is
        # adopted by adopt_found_lattice), else the job's (with the lattice found, if one was).
        doc = getattr(job, "shown_doc", None) or getattr(job, "doc", doc)
        self.pending = None
        self.found_lattice = getattr(job, "found", None) if doc.lattice is not None else None
        if job.error or job.cancelled:
            if job.error:
                self.ed.dialogs.message("Could not open", job.error)
            if self.history is None:
                if kind != "new":
                    self.new_document()
                else:
                    self.ed.fail(job.error or "The default exemplar could not be loaded.")
            return
        if path and kind in ("project", "image", "exemplar") and path != self.autosave.path:
            self.remember(path)
        if kind == "exemplar" and self.history is not None:
            self.edit(doc, self.pending_label)
            return
        self.history = History(doc)
        for tool in self.ed.tools:  # what a tool held of the last document (a lattice message...) goes
            tool.new_document()
        self.ed.playback.stop()
        self.autosave.clear()  # a new document: the autosave of the one it replaces goes
        if kind == "project":
            self.ed.viewer.show(proj.view, proj.display)
            self.project_path = path if path != self.autosave.path else None
        elif kind == "recovered":  # the unsaved work of a project (or of an untitled document)
            self.ed.viewer.show(proj.view, proj.display)
            self.project_path = proj.origin if proj.origin and os.path.isfile(proj.origin) else None
            self.history.saved = None
            self._adopt_autosave(path)
        else:
            self.ed.viewer.show()
            self.project_path = None

    def _recover(self, rec: Recoverable) -> None:
        try:
            proj = rec.project  # read now: only the one being recovered is ever held
        except ProjectError as exc:
            self.ed.dialogs.message("Recover unsaved work", f"The autosaved work could not be read ({exc}).")
            return
        self.begin_load("recovered", proj.document, proj, rec.path)

    def _adopt_autosave(self, path: str | None) -> None:
        """The recovered work goes into this editor's own autosave at once;
        then the earlier session's file (only that one) is removed."""
        try:
            self.autosave.tick(self.autosave_project(), True, force=True)
        except ProjectError as exc:
            self.ed.dialogs.message("Autosave", f"The recovered work could not be autosaved again ({exc})\n"
                                 "Its earlier autosave is kept.")
            return
        for rec in self.autosave.pending_all():
            if rec.path == path:
                self.autosave.discard(rec)

    def install_drop_callback(self) -> None:
        try:
            import glfw
            from imgui_bundle import glfw_utils
            win = glfw_utils.glfw_window_hello_imgui()
            glfw.set_drop_callback(win, lambda _w, paths: self._dropped.extend(paths))
        except Exception:
            pass

    def open_dropped(self) -> None:
        """Open what was dropped on the window since the last frame."""
        if len(self._dropped) > 1 and not any(is_project_file(p) for p in self._dropped if os.path.isfile(p)):
            paths, self._dropped = list(self._dropped), []  # several images dropped at once: one material's maps
            self.confirm_discard(lambda: self.open_paths(paths))
        while self._dropped:
            path = self._dropped.pop(0)
            self.confirm_discard(lambda: self.open_path(path))

    def remember(self, path: str) -> None:
        """Put a file at the top of File > Open Recent (kept in the user's config folder)."""
        self.ed.prefs.remember(path)

    # -- history ------------------------------------------------------------

    def edit(self, doc: Document, label: str, group: object = None, region: tuple | None = None) -> None:
        """Apply an edit (one undo step; same ``group`` = same step). A tool
        says where it reached the canvas (``region``: finest-level canvas
        rectangles (x0, y0, x1, y1)); the synthesis redoes just that."""
        if self.history is None:
            return
        try:
            self.history.apply(doc, label, group, region)
        except ProjectError as exc:
            self.ed.dialogs.message("Invalid setting", str(exc))

    def undo(self) -> None:
        if self.history:
            self.history.undo()

    def redo(self) -> None:
        if self.history:
            self.history.redo()

    def new_seed(self) -> None:
        self.edit(replace(self.doc, seed=random.randrange(1, 2 ** 31)), "New seed")

    # -- saving, and the questions before unsaved edits are lost -------------

    def save(self, path: str | None = None) -> bool:
        """Save to ``path`` (else the document's project file), with the project
        extension; never over one of the document's inputs."""
        path = path or self.project_path
        if path is None:
            self.save_as()
            return False
        try:
            path = project_save_path(path, self.doc, self.project_path)
            save_project(path, self.project())
        except ProjectError as exc:
            self.ed.dialogs.message("Save failed", f"{exc}\nNothing was changed on disk.")
            return False
        self.project_path = path
        self.remember(path)
        self.history.mark_saved()
        self.autosave.clear()
        return True

    def save_as(self, then=None) -> None:
        """Ask where to save; ``then()`` runs once the project is saved. The
        editor asks before replacing a file the system's dialog did not
        already ask about (the in-window chooser and path box, or a name that
        got the project extension)."""
        native = []

        def done(path: str) -> None:
            self.save_chosen(path, bool(native), then)
        name = self.project_path or "untitled" + PROJECT_SUFFIX  # a bare name goes to Dialogs.start_dir()
        self.ed.dialogs.ask_path("Save project as", True, PROJECT_FILTER, done, default=name)
        req = self.ed.dialogs.path_request
        if req is not None and req.native is not None:
            native.append(True)

    def save_chosen(self, chosen: str, asked: bool = False, then=None) -> None:
        """Save to the file the user chose (``asked``: the system's dialog
        already asked about replacing ``chosen``); asks before replacing any
        other existing file; refuses the document's inputs in one line."""
        try:
            path = project_save_path(chosen, self.doc, self.project_path)
        except ProjectError as exc:
            self.ed.dialogs.message("Save failed", f"{exc}\nNothing was changed on disk.")
            return

        def write() -> None:
            if self.save(path) and then is not None:
                then()
        own = self.project_path is not None and os.path.abspath(self.project_path) == path
        if os.path.lexists(path) and not own and not (asked and path == os.path.abspath(chosen)):
            self.ed.dialogs.ask("Replace file", f"{printable(os.path.basename(path))} already exists in "
                             f"{printable(os.path.dirname(path))}. Replace it?",
                             [("Replace", write), ("Cancel", None)])
        else:
            write()

    def save_then(self, action) -> None:
        """Save (asking where for an untitled document), then run ``action``."""
        if self.project_path is None:
            self.save_as(then=action)
        elif self.save():
            action()

    def confirm_discard(self, action) -> None:
        """Run ``action`` (which replaces the document), offering to save unsaved edits first."""
        if self.history is not None and self.history.dirty:
            self.ed.dialogs.ask("Unsaved changes", f"{self.title.split(' - ')[0].lstrip('*')} has unsaved changes. "
                             "Save them first?",
                             [("Save", lambda: self.save_then(action)), ("Discard", action), ("Cancel", None)])
        else:
            action()

    def request_quit(self) -> None:
        """Quit, asking first when there are unsaved edits (menu, Ctrl+Q, window close)."""
        def quit_now():
            if self.history is not None:
                self.history.saved = self.history.current
            self.quit_requested = True

        def save_and_quit():
            self.save_then(quit_now)
        if self.history is not None and self.history.dirty:
            self.ed.dialogs.ask("Unsaved changes", "The project has unsaved changes. Save them before quitting?",
                             [("Save", save_and_quit), ("Discard", quit_now), ("Cancel", None)])
        else:
            quit_now()

    def close_requested(self) -> None:
        """In the frame: the window's close button was pressed with unsaved
        edits (``confirm_exit``): ask now."""
        if self._close_requested:
            self._close_requested = False
            self.request_quit()

    def confirm_exit(self) -> bool:
        # Called by the runner outside the frame (no imgui calls here): defer to a modal.
        if self.history is not None and self.history.dirty and not self.ed.screenshot:
            self._close_requested = True
            return False
        return True

    def autosave_tick(self) -> None:
        if self.doc is not None and self.history is not None:
            try:
                self.autosave.tick(self.autosave_project(), self.history.dirty)
            except ProjectError:
                pass

    def keep_unsaved_work(self) -> None:
        """On exit: unsaved edits stay in this editor's autosave (offered at the
        next start), else it goes; other editors' autosaves are not touched."""
        if self.history is not None and self.history.dirty:
            try:
                self.autosave.tick(self.autosave_project(), True, force=True)  # keep unsaved work for recovery
            except ProjectError:
                pass
        else:
            self.autosave.close()


def recovery_question(rec: Recoverable, i: int = 0, n: int = 1) -> str:
    """The start-up question about one earlier session's unsaved work."""
    t = time.strftime("%Y-%m-%d %H:%M", time.localtime(rec.time))
    origin, name = rec.origin, rec.name
    what = printable(os.path.basename(origin)) if origin else f"untitled ({printable(name)})"
    count = f" ({i + 1} of {n})" if n > 1 else ""
    return (f"An Infinitex session did not close normally. Unsaved work on {what} from {t} was kept{count}.\n"
            "Recover it? (Keep for later: asked again at the next start.)")


def adopt_found_lattice(ed, job) -> None:
    """A lattice the analysis job found after its quick preview was shown:
    the document goes on it, one undo step ("Lattice found"), with a notice;
    the job's analysis is the one installed, so nothing waits again. Not
    where the document was since given something a lattice does not go with,
    or another exemplar."""
    found = getattr(job, "found", None)
    doc = ed.doc
    lattice = job.doc.lattice
    if found is None or lattice is None or doc is None or doc.lattice is not None or not may_find_lattice(doc):
        return
    if doc.analysis_key() != job.asked_key:
        return
    ed.edit(replace(doc, lattice=lattice), "Lattice found")
    ed.files.found_lattice = found
    ed.tell(f"Found a lattice (cells {lattice.describe()}): rows and columns stay straight. "
            "Ctrl+Z synthesizes without it.")
