"""What stops an export, as exceptions the editor and the command line report."""


class ExportInterrupted(Exception):
    """Raised by a progress callback to stop; the finished tiles are kept."""


class ExportFailed(RuntimeError):
    """The workers could not finish (they keep dying, the cluster is out of
    reach); a sentence for the user. The finished tiles are kept."""


class ExportCancelled(Exception):
    """The user cancelled a window export."""
