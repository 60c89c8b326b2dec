"""Where the project's files are and where generated files go."""
import os
from pathlib import Path

__all__ = ["ROOT", "BUILD"]

#: The source checkout (or the installed packages' folder).
ROOT = Path(__file__).resolve().parents[1]


def _build_dir():
    """Where generated files go: ``$STEREO_BUILD_DIR`` if set, ``build/`` of the source
    checkout, or ``build/`` under the working directory for an installed package (whose
    site-packages is no place for build output)."""
    if os.environ.get("STEREO_BUILD_DIR"):
        return Path(os.environ["STEREO_BUILD_DIR"]).resolve()
    if (ROOT / "pyproject.toml").is_file():
        return ROOT / "build"
    return Path.cwd().resolve() / "build"


#: The one build directory every generator and backend writes under.
BUILD = _build_dir()
