"""Key presses as the window system delivered them, each with the modifiers
held at that moment: what the editor's shortcuts read.

imgui spreads fast input over frames (its trickle queue) but keeps one
modifier state per frame. A chord whose Ctrl goes up in the same batch of
events as its letter goes down (``xdotool key ctrl+o`` releases in the order
it pressed; a fast typist; an editor woken from its idle sleep by the whole
chord at once) reached the frame as a plain letter: Ctrl+O was lost and the
"o" went to the canvas as a tool key. Here every press is kept, in order,
with the modifiers glfw reports for it, however short the chord and however
many arrive between two frames.

Under the imgui test engine (the GUI drivers inject keys into imgui, not into
the window system) the log is inactive and the same questions are asked of
imgui's per-frame key state.
"""
from __future__ import annotations

from functools import lru_cache

from imgui_bundle import imgui

CTRL, SHIFT, ALT, SUPER = 2, 1, 4, 8  # glfw's modifier bits
_MODS = CTRL | SHIFT | ALT | SUPER


def _glfw_key(key: imgui.Key) -> int | None:
    """glfw's key code of an imgui key (the keys the editor's shortcuts use)."""
    return _glfw_code(int(key))


@lru_cache(maxsize=None)
def _glfw_code(k: int) -> int | None:
    import glfw
    K = imgui.Key
    for first, last, gfirst in ((K.a, K.z, glfw.KEY_A), (K._0, K._9, glfw.KEY_0), (K.f1, K.f12, glfw.KEY_F1),
                                (K.keypad0, K.keypad9, glfw.KEY_KP_0)):
        if int(first) <= k <= int(last):
            return gfirst + k - int(first)
    named = {K.slash: glfw.KEY_SLASH, K.equal: glfw.KEY_EQUAL, K.minus: glfw.KEY_MINUS,
             K.keypad_add: glfw.KEY_KP_ADD, K.keypad_subtract: glfw.KEY_KP_SUBTRACT,
             K.escape: glfw.KEY_ESCAPE, K.left_bracket: glfw.KEY_LEFT_BRACKET,
             K.right_bracket: glfw.KEY_RIGHT_BRACKET}
    return next((g for i, g in named.items() if int(i) == k), None)


def _layout_key(key: int, scancode: int) -> int:
    """The key as the keyboard layout names it (as imgui's glfw backend does:
    on AZERTY, the key at US "Q" is "A"), for letters and digits."""
    import glfw
    if not (glfw.KEY_0 <= key <= glfw.KEY_9 or glfw.KEY_A <= key <= glfw.KEY_Z
            or key in (glfw.KEY_SLASH, glfw.KEY_EQUAL, glfw.KEY_MINUS)):
        return key
    try:
        name = glfw.get_key_name(key, scancode)
    except Exception:
        return key
    if isinstance(name, bytes):
        name = name.decode("utf-8", "replace")
    if name and len(name) == 1:
        c = name.upper()
        if "A" <= c <= "Z" or "0" <= c <= "9":
            return ord(c)  # glfw's codes for letters and digits are their ASCII codes
        return {"/": glfw.KEY_SLASH, "=": glfw.KEY_EQUAL, "-": glfw.KEY_MINUS}.get(c, key)
    return key


class KeyLog:
    """The key presses since the last frame, each with its own modifiers."""

    def __init__(self) -> None:
        self.active = False        # installed on a real window (not the test engine)
        self._pending: list[tuple[int, int]] = []   # (glfw key, modifier bits), delivered since the frame began
        self._frame: list[tuple[int, int]] = []     # this frame's
        self._address = 0
        self._callback = None      # kept alive: glfw holds only a C pointer to it

    def install(self, window) -> bool:
        """Take the window's key events (and pass each on to imgui's backend)."""
        import ctypes

        import glfw
        try:
            self._address = ctypes.cast(window, ctypes.c_void_p).value or 0
            if not self._address:
                return False
            self._callback = self._on_key
            glfw.set_key_callback(window, self._callback)
        except Exception:
            return False
        self.active = True
        return True

    def _on_key(self, _window, key: int, scancode: int, action: int, mods: int) -> None:
        import glfw
        if action == glfw.PRESS:
            self._pending.append((_layout_key(int(key), scancode), int(mods) & _MODS))
        imgui.backends.glfw_key_callback(self._address, key, scancode, action, mods)

    def new_frame(self) -> None:
        """A frame begins: the presses delivered since the last one are its own."""
        self._frame, self._pending = self._pending, []

    @property
    def waiting(self) -> bool:
        """Presses were delivered since this frame began (the next must not sleep)."""
        return bool(self._pending)

    def take(self, key: imgui.Key, ctrl: bool = False, shift: bool | None = False) -> int:
        """How many times ``key`` went down this frame with exactly Ctrl as
        ``ctrl`` (and Shift as ``shift``; None: either), Alt and Super up.
        Each press counts once: taken, it is not seen again this frame."""
        if not self.active:
            return self._imgui(key, ctrl, shift)
        code = _glfw_key(key)
        want = CTRL if ctrl else 0
        n = 0
        keep = []
        for k, m in self._frame:
            mods = m if shift is not None else m & ~SHIFT
            if k == code and mods == (want | (SHIFT if shift else 0)):
                n += 1
            else:
                keep.append((k, m))
        self._frame = keep
        return n

    def plain(self, key: imgui.Key, shift: bool | None = None) -> bool:
        """``key`` went down with no Ctrl, Alt or Super (a tool key, H, T, M)."""
        return self.take(key, False, shift) > 0

    def drop(self) -> None:
        """Forget the rest of this frame's presses (a dialog now takes the keys)."""
        self._frame = []

    @staticmethod
    def _imgui(key: imgui.Key, ctrl: bool, shift: bool | None) -> int:
        io = imgui.get_io()
        if shift is None:
            shift = io.key_shift
        if ctrl:
            chord = imgui.Key.mod_ctrl | key
            if shift:
                chord |= imgui.Key.mod_shift
            return int(imgui.is_key_chord_pressed(chord))
        if io.key_ctrl or io.key_alt or io.key_super or io.key_shift != shift:
            return 0
        return int(imgui.is_key_pressed(key, False))
