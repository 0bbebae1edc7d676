"""The user's settings kept between runs: recent files, the window size, the
side-panel sections left open.

A small JSON file in the user's config folder (``$INFINITEX_CONFIG``, else
``$XDG_CONFIG_HOME/infinitex``, else ``~/.config/infinitex``; with
``INFINITEX_STATE`` set, as in the tests, that folder). It is untrusted input
like any file: size-limited, bounded parse, every field checked; a damaged
file is ignored (and replaced on the next write). Writes are atomic. Imports
neither GL nor imgui.
"""
from __future__ import annotations

import os
import stat
import time
from dataclasses import dataclass, replace

from infinitex.engine.safeio import JSONLimitError, ReadError, WriteError, atomic_write, parse_json, read_limited

RECENT_MAX = 10
MAX_BYTES = 256 * 1024
INI_MAX_BYTES = 1024 * 1024  # imgui.ini: a few KB in practice


def config_dir() -> str:
    if os.environ.get("INFINITEX_CONFIG"):
        return os.environ["INFINITEX_CONFIG"]
    if os.environ.get("INFINITEX_STATE"):
        return os.environ["INFINITEX_STATE"]
    base = os.environ.get("XDG_CONFIG_HOME") or os.path.join(os.path.expanduser("~"), ".config")
    return os.path.join(base, "infinitex")


def settings_path() -> str:
    return os.path.join(config_dir(), "settings.json")


def check_config_file(path: str, limit: int = INI_MAX_BYTES) -> tuple[bool, str | None]:
    """Make a config file that a library opens with a plain blocking open()
    safe to start with (imgui's ini: hello_imgui reads it at start-up and
    writes it on exit; a FIFO there would block the editor forever). Checked
    without opening it: anything but a regular file of at most ``limit`` bytes
    (or a link to one) -- a FIFO, device, socket, folder, broken link, or a
    larger file -- is renamed aside (``NAME.set-aside-TIME``), never deleted.
    Returns (usable, a note for the user or None); not usable (it could not be
    set aside): leave the file off for this run."""
    name = os.path.basename(path)
    try:
        st = os.stat(path)  # follows links; never opens (a FIFO cannot block here)
    except FileNotFoundError:
        if not os.path.islink(path):
            return True, None
        what = "a broken link"
    except OSError as exc:
        return False, f"{name} cannot be checked ({exc.strerror or exc}); the window layout is not kept this time."
    else:
        if stat.S_ISREG(st.st_mode) and st.st_size <= limit:
            return True, None
        what = ("a folder" if stat.S_ISDIR(st.st_mode) else f"larger than {limit // 1024} KB"
                if stat.S_ISREG(st.st_mode) else "not a regular file (a FIFO, device or socket)")
    aside = f"{path}.set-aside-{time.strftime('%Y%m%d-%H%M%S')}"
    try:
        if os.path.lexists(aside):
            raise FileExistsError(aside)
        os.rename(path, aside)
    except OSError:
        return False, (f"{name} in {config_dir()} is {what}; it is left alone and the window layout is not "
                       "kept this time.")
    return True, f"{name} in {config_dir()} was {what}; it was moved to {os.path.basename(aside)}."


@dataclass(frozen=True)
class Settings:
    recent: tuple[str, ...] = ()                  # absolute paths, most recent first
    window: tuple[int, int] | None = None         # the window's size when the editor last closed
    panels: tuple[str, ...] | None = None         # the side-panel sections left open (None: the defaults)

    def with_recent(self, path: str) -> Settings:
        p = os.path.abspath(path)
        return replace(self, recent=(p, *[r for r in self.recent if r != p])[:RECENT_MAX])

    def without_recent(self, path: str) -> Settings:
        return replace(self, recent=tuple(r for r in self.recent if r != path))


def load_settings(path: str | None = None) -> Settings:
    """The saved settings, or the defaults when there are none or they are damaged."""
    path = path or settings_path()
    try:
        d = parse_json(read_limited(path, MAX_BYTES, "settings file"), max_depth=3)
    except (ReadError, JSONLimitError, ValueError, UnicodeDecodeError, FileNotFoundError):
        return Settings()
    except OSError:
        return Settings()
    if not isinstance(d, dict):
        return Settings()
    recent = d.get("recent", [])
    if not isinstance(recent, list):
        recent = []
    recent = tuple(r for r in recent if isinstance(r, str) and 0 < len(r) <= 4096 and "\x00" not in r
                   and os.path.isabs(r))[:RECENT_MAX]
    window = d.get("window")
    if not (isinstance(window, list) and len(window) == 2
            and all(isinstance(v, int) and not isinstance(v, bool) and 320 <= v <= 16384 for v in window)):
        window = None
    panels = d.get("panels")
    if isinstance(panels, list) and len(panels) <= 32 and all(isinstance(p, str) and len(p) <= 64 for p in panels):
        panels = tuple(panels)
    else:
        panels = None
    return Settings(recent, None if window is None else (window[0], window[1]), panels)


def save_settings(s: Settings, path: str | None = None) -> bool:
    """Write atomically; False (and nothing else) when it cannot be written."""
    import json
    path = path or settings_path()
    data = {"recent": list(s.recent), "window": list(s.window) if s.window else None,
            "panels": None if s.panels is None else list(s.panels)}
    try:
        os.makedirs(os.path.dirname(path), exist_ok=True)
        atomic_write(path, json.dumps(data, indent=1).encode("utf-8"), follow_links=True)  # (a dotfile manager's link)
    except (OSError, WriteError):
        return False
    return True
