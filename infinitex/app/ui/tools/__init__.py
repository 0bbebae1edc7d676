"""Canvas tools: each has its own module with press / drag / release handling,
its options panel and its overlay; a gesture (press to release) is one undo
step. The editor routes the left mouse button to the active tool; the right
and middle buttons always pan.

A tool declares what the editor needs to know of it (:class:`Tool`: the space
it works in, whether it shows what is painted, its panel section, whether a
model view offers it, its floating window, its handles, and what it does on a
model, :meth:`Tool.model_gesture`); the editor never compares tool names."""
from __future__ import annotations


MAX_CANVAS_RADIUS = 512.0  # canvas pixels: a brush zoomed far out still edits a bounded area (a dab of
#                            this radius takes about 60 ms to paint on this 2-core machine)


class ModelGesture:
    """What a tool's left button does on a model: the same tool seen through
    the model view's mapping (screen positions in the canvas of w x h)."""

    def __init__(self, ed):
        self.ed = ed

    def press(self, mx: float, my: float, w: int, h: int) -> None:
        pass

    def drag(self, mx: float, my: float, w: int, h: int) -> None:
        pass

    def release(self) -> None:
        pass

    def finish(self, mx: float, my: float, w: int, h: int) -> None:
        """The button came up at (mx, my): a move in the release's frame counts, then release."""
        self.drag(mx, my, w, h)
        self.release()

    def wheel(self, mx: float, my: float, w: int, h: int, amount: float) -> bool:
        """The wheel over the model; True when used (else it zooms the camera)."""
        return False

    def drop(self, u: tuple[int, int], mx: float, my: float, w: int, h: int) -> None:
        """An exemplar point dropped at (mx, my)."""

    def draw(self, draw_list, p0, w: int, h: int) -> None:
        """Drawn over the model whether hovered or not (handles)."""

    def cursor(self, draw_list, mouse: tuple[float, float]) -> None:
        """Drawn at the mouse while it is over the model."""


class BrushGesture(ModelGesture):
    """A brush on the model: its circle at the mouse (the active tool's
    ``brush.radius``, screen pixels)."""

    def cursor(self, draw_list, mouse: tuple[float, float]) -> None:
        from imgui_bundle import imgui
        r = self.ed.tool.brush.radius
        draw_list.add_circle(mouse, r, imgui.get_color_u32((0, 0, 0, 0.8)), 0, 3.0)
        draw_list.add_circle(mouse, r, imgui.get_color_u32((1, 1, 1, 0.9)), 0, 1.5)


class Tool:
    """Base class. Positions are finest-level canvas pixels (floats)."""

    name = "tool"
    label = "Tool"
    key = ""          # shortcut letter
    tooltip = ""
    space = ""        # "canvas": works on the synthesized canvas (shown rectified while active);
    #                   "exemplar": on the exemplar, in the tool's own window
    shows_painted = False  # choosing it turns "Show painted" (H) on
    panel = "Brush"   # the side panel's section of its options ("": none)
    on_model = True   # offered while a model is open

    def __init__(self, ed):
        self.ed = ed

    def press(self, pos: tuple[float, float], screen: tuple[float, float]) -> None:
        pass

    def drag(self, pos: tuple[float, float], screen: tuple[float, float]) -> None:
        pass

    def release(self) -> None:
        pass

    def new_document(self) -> None:
        """Another document was opened: forget what belonged to the last one
        (messages, selections, drafts); the tool's own settings stay."""

    def options(self) -> None:
        """Tool options, drawn in the Tools panel."""

    def offer_lattice_off(self, note: str) -> bool:
        """For a tool that does not go with a lattice, at the top of its options:
        while the document has one, say so (``note``) before any stroke and
        offer to turn it off in one undo step. True when it has one (the
        options stop there)."""
        ed = self.ed
        if ed.doc.lattice is None:
            return False
        from dataclasses import replace

        from imgui_bundle import imgui
        imgui.text_wrapped(note + " Turn the lattice off to paint one (Undo brings it back).")
        if imgui.button(f"Turn the lattice off##{self.name}-lattice-off", (-1, 0)):
            ed.edit(replace(ed.doc, lattice=None), "Lattice off")
        return True

    def overlay(self, draw_list, p0, w: int, h: int) -> None:
        """Drawn over the canvas (cursor, handles)."""

    def keys(self) -> None:
        """Per-frame keyboard shortcuts while the tool is active."""

    def atlas_overlay(self, doc, n: int):
        """What "Show painted" (H) draws over a model while this tool is active:
        (key, a function making the n x n RGBA8 overlay), or None for the
        painted randomness (the default)."""
        return None

    def wheel(self, pos: tuple[float, float], amount: float) -> bool:
        """The mouse wheel over the canvas; True when the tool used it (else it zooms)."""
        return False

    def handles(self, draw_list, p0, w: int, h: int) -> None:
        """Drawn over the canvas whether hovered or not (the features' handles)."""

    def window(self) -> None:
        """Its own floating window, drawn each frame while the tool is active."""

    def model_gesture(self) -> ModelGesture | None:
        """What the left button does on a model (None: it orbits)."""
        return None


class Tools(list):
    """The editor's tools in tool bar order (Navigate first), and the active
    one (``active``, changed by ``choose`` alone)."""

    def __init__(self, tools, ed=None):
        super().__init__(tools)
        self.ed = ed
        self.active: Tool | None = self[0] if self else None

    def choose(self, t: Tool) -> None:
        """Make ``t`` the active tool."""
        ed = self.ed
        if t.space == "canvas" and ed.geometry() is not None:
            # Paint and features live on the synthesized canvas: show it rectified.
            ed.viewer.set_display(geometry="rectified")
        if t is not self.active:
            self.active.release()
            self.active = t
            if t.shows_painted:
                ed.viewer.show_painted(True)  # painting shows what is painted

    def of(self, cls: type) -> Tool:
        """The tool of class ``cls``."""
        return next(t for t in self if isinstance(t, cls))

    def offered(self, model: bool) -> list[Tool]:
        """The tools the tool bar and their keys offer (``model``: while a model is shown)."""
        return [t for t in self if t.on_model or not model]


def begin_tool_window(ed, tool, title: str, size: tuple[float, float], image: tuple[int, int],
                      zoom_range: tuple[float, float], fmt: str) -> bool:
    """A tool's own zoomable image window (Paint exemplar, Lattice):
    placed at the top right on first use, closing it goes back to Navigate,
    a zoom slider (``tool.zoom``) and the image size on its first row. Returns
    whether its content is visible; call ``imgui.end()`` after it, always."""
    from imgui_bundle import imgui
    vp = imgui.get_main_viewport()
    imgui.set_next_window_size(size, imgui.Cond_.first_use_ever)
    imgui.set_next_window_pos((vp.work_pos.x + vp.work_size.x - size[0] - 24, vp.work_pos.y + 64),
                              imgui.Cond_.first_use_ever)
    opened, keep = imgui.begin(title, True)
    if not keep:
        ed.tools.choose(ed.tools[0])
    if opened:
        imgui.set_next_item_width(160)
        _, tool.zoom = imgui.slider_float("Zoom", tool.zoom, zoom_range[0], zoom_range[1], fmt,
                                          imgui.SliderFlags_.logarithmic)
        imgui.same_line()
        imgui.text_disabled(f"{image[0]}x{image[1]} px")
    return opened

def make_tools(ed) -> Tools:
    from .direction import DirectionTool
    from .feature import FeatureTool
    from .flow import FlowTool
    from .labels import LabelTool
    from .lattice import LatticeTool
    from .navigate import NavigateTool
    from .paint import PaintCanvasTool, PaintExemplarTool
    return Tools([NavigateTool(ed), PaintCanvasTool(ed), PaintExemplarTool(ed), FeatureTool(ed), LabelTool(ed),
                  DirectionTool(ed), FlowTool(ed), LatticeTool(ed)], ed)
