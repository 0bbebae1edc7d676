"""The user's settings kept between runs (app/settings.py: recent files, the
window's size, the open panel sections): their one owner in the editor."""
from __future__ import annotations

from dataclasses import replace

from ..settings import Settings, load_settings, save_settings


class Preferences:
    def __init__(self, settings: Settings | None = None) -> None:
        self.settings = settings if settings is not None else load_settings()

    def remember(self, path: str) -> None:
        """Put a file at the top of File > Open Recent (kept in the user's config folder)."""
        self.settings = self.settings.with_recent(path)
        save_settings(self.settings)

    def forget(self, path: str | None) -> None:
        """Take a file off File > Open Recent (None: every file)."""
        self.settings = replace(self.settings, recent=()) if path is None else self.settings.without_recent(path)
        save_settings(self.settings)

    def keep_window(self, size: tuple[int, int], panels_open) -> None:
        """On exit: the window's size and the open panel sections, for the next run."""
        if size[0] >= 320 and size[1] >= 320:
            self.settings = replace(self.settings, window=(int(size[0]), int(size[1])),
                                    panels=tuple(sorted(panels_open)))
            save_settings(self.settings)
