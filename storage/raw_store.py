"""Content-addressed store of raw record files: ``<root>/<sha256[:2]>/<sha256><suffix>``.

A file is kept (copied, then atomically renamed into place) BEFORE it is processed, so every
stored result can be reproduced from the exact bytes it came from. Keeping the same content
twice is a no-op. The root comes from the caller (settings ``GEARWATCH_RAW_STORE``, default
``./raw-store``).
"""

from __future__ import annotations

import hashlib
import os
import re
import shutil
import tempfile
from pathlib import Path

from gearwatch.floor.errors import InputError

_SHA256 = re.compile(r"^[0-9a-f]{64}$")
_SUFFIX = re.compile(r"^(\.[A-Za-z0-9_-]{1,16}){0,3}$")
DEFAULT_RAW_STORE = Path("./raw-store")


class RawStore:
    """A content-addressed file store rooted at ``root`` (created on first use)."""

    def __init__(self, root: str | Path = DEFAULT_RAW_STORE) -> None:
        # Absolute, so that the locations stored in the database do not depend on the
        # working directory of whoever reads them later (service, CLI, workers).
        self.root = Path(root).expanduser().absolute()

    def path_for(self, sha256: str, suffix: str = "") -> Path:
        if not _SHA256.match(sha256):
            raise InputError(f"not a sha256 hex digest: {sha256!r}")
        if not _SUFFIX.match(suffix):
            raise InputError(f"unsafe file suffix {suffix!r}")
        return self.root / sha256[:2] / f"{sha256}{suffix}"

    def contains(self, sha256: str, suffix: str = "") -> bool:
        return self.path_for(sha256, suffix).is_file()

    def keep(self, source: str | Path, sha256: str | None = None, suffix: str | None = None) -> Path:
        """Copy ``source`` into the store (unless that content is already there); its path.

        ``sha256`` is checked against the bytes actually copied; a mismatch (the file changed
        while being kept) is an :class:`InputError` and nothing is kept. ``suffix`` defaults to
        the source's last suffix.
        """
        source = Path(source)
        suffix = source.suffix if suffix is None else suffix
        if sha256 is not None:
            target = self.path_for(sha256, suffix)
            if target.is_file():
                return target
        self.root.mkdir(parents=True, exist_ok=True)
        digest = hashlib.sha256()
        handle, tmp_name = tempfile.mkstemp(prefix=".keep-", dir=self.root)
        try:
            with os.fdopen(handle, "wb") as out, open(source, "rb") as stream:
                while chunk := stream.read(1 << 20):
                    digest.update(chunk)
                    out.write(chunk)
                out.flush()
                os.fsync(out.fileno())
            actual = digest.hexdigest()
            if sha256 is not None and actual != sha256:
                raise InputError(f"{source}: content changed while it was being kept")
            target = self.path_for(actual, suffix)
            target.parent.mkdir(parents=True, exist_ok=True)
            if target.is_file():
                os.unlink(tmp_name)
            else:
                os.chmod(tmp_name, 0o444)  # raw evidence is never edited in place
                os.replace(tmp_name, target)
            return target
        except BaseException:
            if os.path.exists(tmp_name):
                os.unlink(tmp_name)
            raise

    def keep_bytes(self, data: bytes, suffix: str = "") -> tuple[str, Path]:
        """Keep in-memory content (an upload, CAN frames); returns its sha256 and path."""
        sha256 = hashlib.sha256(data).hexdigest()
        target = self.path_for(sha256, suffix)
        if not target.is_file():
            target.parent.mkdir(parents=True, exist_ok=True)
            handle, tmp_name = tempfile.mkstemp(prefix=".keep-", dir=target.parent)
            with os.fdopen(handle, "wb") as out:
                out.write(data)
            os.chmod(tmp_name, 0o444)
            os.replace(tmp_name, target)
        return sha256, target

    def copy_out(self, sha256: str, suffix: str, destination: str | Path) -> Path:
        shutil.copyfile(self.path_for(sha256, suffix), destination)
        return Path(destination)
