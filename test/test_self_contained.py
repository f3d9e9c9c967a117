"""The repository stands on its own: no tracked file points the reader at notes or a paper that
a user of the repository does not have (the docs pages and the paper's reference do instead)."""

import subprocess
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
# Spelled in pieces so that this file does not name them itself.
OUTSIDE = ("DESIGN" + ".md", ".." + "/shared", "shared" + "/paper")


def tracked_files() -> list[Path]:
    """Every file git tracks (a source tree without git: every file outside the usual
    untracked directories)."""
    try:
        names = subprocess.run(["git", "ls-files", "-z"], cwd=REPO, capture_output=True,
                               check=True).stdout.decode().split("\0")
        return [REPO / n for n in names if n]
    except (OSError, subprocess.CalledProcessError):
        skip = {".git", ".venv", ".venv-jazzy", "out", "build", "install", "log", "bags",
                "__pycache__", "_build", "_generated"}
        return [p for p in REPO.rglob("*")
                if p.is_file() and not skip & set(p.relative_to(REPO).parts)]


def test_no_shipped_file_points_outside_the_repository():
    me = Path(__file__).resolve()
    found = []
    for path in tracked_files():
        if path.resolve() == me or not path.is_file():
            continue
        try:
            text = path.read_text(encoding="utf-8")
        except UnicodeDecodeError:
            continue  # binary (the docs' figures)
        for n, line in enumerate(text.splitlines(), 1):
            found += [f"{path.relative_to(REPO)}:{n}: {word}" for word in OUTSIDE if word in line]
    assert not found, "\n".join(found)
