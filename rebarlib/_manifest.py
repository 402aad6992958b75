"""What a result was made from: the manifest stored in every ``result.json``.

A result is only worth judging if it belongs to the captures and design it is judged against.
``make_manifest`` records the capture folder and a digest of its files, the design file's digest,
the method and options, the rebarlib version and the time; ``manifest_problems`` compares a
stored manifest with the inputs at hand and lists every difference in words.

The digest of a capture is SHA-256 over the sorted names and SHA-256 digests of the regular
files directly in its folder (sub-folders are not inputs), so renaming, editing, adding or
removing any file changes it.
"""

from __future__ import annotations

import hashlib
from datetime import datetime, timezone
from pathlib import Path

__all__ = ["file_digest", "capture_digest", "make_manifest", "manifest_problems"]

_CHUNK = 1 << 20


def file_digest(path) -> str:
    """SHA-256 of a file's bytes, as ``"sha256:<hex>"``."""
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(_CHUNK), b""):
            h.update(block)
    return "sha256:" + h.hexdigest()


def capture_digest(folder) -> str:
    """SHA-256 over the names and digests of the regular files directly in ``folder``."""
    h = hashlib.sha256()
    for p in sorted(Path(folder).iterdir(), key=lambda q: q.name):
        if p.is_file():
            h.update(p.name.encode("utf-8") + b"\0" + file_digest(p).encode("ascii") + b"\n")
    return "sha256:" + h.hexdigest()


def make_manifest(capture_folder, design_path, *, method: str, options: dict | None = None) -> dict:
    """The manifest of one result: inputs (with digests), method, options, version and time.

    ``design_path`` may be None when the design was given as an object, not a file;
    ``capture_folder`` None when the input is not a capture folder (a scanned cloud's file is
    recorded by :func:`rebarlib.scan.cloud_manifest`), and then no folder is read.
    """
    from . import __version__

    cap = None if capture_folder is None else Path(capture_folder).resolve()
    return {
        "capture_folder": None if cap is None else str(cap),
        "capture_digest": None if cap is None else capture_digest(cap),
        "design_file": None if design_path is None else str(Path(design_path).resolve()),
        "design_digest": None if design_path is None else file_digest(design_path),
        "method": method,
        "options": dict(options or {}),
        "rebarlib_version": __version__,
        "created_at": datetime.now(timezone.utc).isoformat(timespec="seconds"),
    }


def manifest_problems(
    manifest: dict | None,
    *,
    capture_folder=None,
    design_path=None,
    method: str | None = None,
    version: str | None = None,
) -> list:
    """Differences between a stored manifest and the inputs at hand, as sentences.

    Each keyword left None is not compared. An empty list means the result belongs to them.
    """
    if not isinstance(manifest, dict):
        return ["it has no manifest (written by an older rebarlib or by hand): re-run `rebar inspect`"]
    out = []
    if capture_folder is not None:
        cap = Path(capture_folder).resolve()
        if cap.is_file():  # a scanned cloud (``rebar inspect-cloud``): its own digest
            if manifest.get("cloud_digest") != file_digest(cap):
                out.append(f"the cloud file {cap.name} is not the one the result was made from")
        elif manifest.get("capture_digest") != capture_digest(cap):
            out.append(f"the files of capture {cap.name} changed since the result was made")
    if design_path is not None and manifest.get("design_digest") != file_digest(design_path):
        out.append(f"it was made against another design file than {Path(design_path).name}")
    if method is not None and manifest.get("method") != method:
        out.append(f"it was made with method {manifest.get('method')!r}, not {method!r}")
    if version is not None and manifest.get("rebarlib_version") != version:
        out.append(f"it was made by rebarlib {manifest.get('rebarlib_version')}, not {version}")
    return out
