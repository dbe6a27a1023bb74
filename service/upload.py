"""Streaming multipart upload: the body is read only AFTER the caller was authenticated and
authorised, and only into the configured upload folder, with the size limit enforced while
the bytes arrive.

Why not FastAPI's ``UploadFile``/``Form`` parameters: FastAPI parses a multipart body (into
temporary files of the *system* temp folder, of any size) before it runs the route's
dependencies, so an anonymous caller could fill the disk before being told 401. The upload
route therefore declares no body parameter; its handler runs after the key and role
dependencies and calls :func:`receive_upload`, which feeds ``request.stream()`` to
python-multipart's push parser.

Limits: ``Content-Length`` (when sent) is checked before the first byte is read; the file
part is counted while it is written and the request ends with 413 as soon as it passes
``max_upload_bytes``; the other form fields together may hold :data:`MAX_FIELD_BYTES`; at most
:data:`MAX_PARTS` parts.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Any

from python_multipart.multipart import MultipartParser, parse_options_header
from starlette.requests import Request

from gearwatch.floor.errors import GearwatchError, InputError

MAX_FIELD_BYTES = 64 * 1024
"""All non-file form fields together (the manifest entry is a few hundred bytes)."""
MAX_PARTS = 8
FORM_OVERHEAD_BYTES = MAX_FIELD_BYTES + 16 * 1024
"""What a request may carry beyond the file itself: fields, part headers, boundaries."""

_UNSAFE = re.compile(r"[^A-Za-z0-9._+-]")

UPLOAD_REQUEST_BODY: dict[str, Any] = {
    "required": True,
    "content": {
        "multipart/form-data": {
            "schema": {
                "type": "object",
                "required": ["file", "entry"],
                "properties": {
                    "file": {
                        "type": "string",
                        "format": "binary",
                        "description": "The record file.",
                    },
                    "entry": {
                        "type": "string",
                        "description": "The manifest entry as JSON: taken_at (ISO 8601 with "
                        "time zone), optional label and file.",
                        "examples": ['{"taken_at": "2026-03-02T08:00:00Z", "label": "day 2"}'],
                    },
                },
            }
        }
    },
}
"""The OpenAPI description of the form :func:`receive_upload` reads (no body parameter is
declared on the route, see the module docstring)."""


class PayloadTooLarge(GearwatchError):
    http_status = 413
    code = "payload_too_large"


@dataclass
class ReceivedUpload:
    """The spooled file part and the text fields of an upload."""

    path: Path | None = None
    filename: str = ""
    size: int = 0
    fields: dict[str, str] = field(default_factory=dict)


class _Receiver:
    """python-multipart callbacks: the ``file`` part into ``folder``, text fields in memory."""

    def __init__(self, folder: Path, max_file_bytes: int) -> None:
        self.folder = folder
        self.max_file_bytes = max_file_bytes
        self.result = ReceivedUpload()
        self.parts = 0
        self.field_bytes = 0
        self._header_name = b""
        self._header_value = b""
        self._headers: dict[bytes, bytes] = {}
        self._name = ""
        self._is_file = False
        self._out: IO[bytes] | None = None
        self._value = bytearray()

    def callbacks(self) -> dict[str, Any]:
        return {
            "on_part_begin": self.part_begin,
            "on_header_field": self.header_field,
            "on_header_value": self.header_value,
            "on_header_end": self.header_end,
            "on_headers_finished": self.headers_finished,
            "on_part_data": self.part_data,
            "on_part_end": self.part_end,
        }

    def part_begin(self) -> None:
        self.parts += 1
        if self.parts > MAX_PARTS:
            raise InputError(f"the form has more than {MAX_PARTS} parts")
        self._headers = {}
        self._name, self._is_file, self._value = "", False, bytearray()

    def header_field(self, data: bytes, start: int, end: int) -> None:
        self._header_name += data[start:end]

    def header_value(self, data: bytes, start: int, end: int) -> None:
        self._header_value += data[start:end]

    def header_end(self) -> None:
        self._headers[self._header_name.lower()] = self._header_value
        self._header_name, self._header_value = b"", b""

    def headers_finished(self) -> None:
        _, options = parse_options_header(self._headers.get(b"content-disposition", b""))
        self._name = options.get(b"name", b"").decode("utf-8", "replace")
        filename = options.get(b"filename")
        if self._name == "file":
            if self.result.path is not None:
                raise InputError("the form has more than one file part")
            self._is_file = True
            self.result.filename = (filename or b"").decode("utf-8", "replace")
            safe = _UNSAFE.sub("_", Path(self.result.filename).name)[-100:] or "record"
            self.result.path = self.folder / safe
            self._out = open(self.result.path, "wb")  # closed in part_end/close

    def part_data(self, data: bytes, start: int, end: int) -> None:
        size = end - start
        if self._is_file:
            self.result.size += size
            if self.result.size > self.max_file_bytes:
                raise PayloadTooLarge(
                    f"the file is larger than the limit of {self.max_file_bytes} bytes"
                )
            assert self._out is not None
            self._out.write(data[start:end])
            return
        self.field_bytes += size
        if self.field_bytes > MAX_FIELD_BYTES:
            raise PayloadTooLarge(f"the form fields are larger than {MAX_FIELD_BYTES} bytes")
        self._value += data[start:end]

    def part_end(self) -> None:
        if self._is_file:
            self.close()
        elif self._name:
            self.result.fields[self._name] = self._value.decode("utf-8", "replace")

    def close(self) -> None:
        if self._out is not None:
            self._out.close()
            self._out = None


def check_declared_length(request: Request, max_file_bytes: int) -> None:
    """413 before reading anything when ``Content-Length`` already says the body is too big."""
    declared = request.headers.get("content-length")
    if declared is None:
        return
    try:
        length = int(declared)
    except ValueError:
        raise InputError("Content-Length is not a number") from None
    if length > max_file_bytes + FORM_OVERHEAD_BYTES:
        raise PayloadTooLarge(
            f"the request ({length} bytes) is larger than the upload limit of "
            f"{max_file_bytes} bytes"
        )


async def receive_upload(request: Request, folder: Path, max_file_bytes: int) -> ReceivedUpload:
    """Stream a ``multipart/form-data`` body into ``folder`` (the file part) and memory (the
    text fields). Raises :class:`PayloadTooLarge` (413) as soon as a limit is passed and
    :class:`InputError` (422) for a body that is not such a form; what was written so far
    stays in ``folder`` for the caller to remove."""
    content_type, options = parse_options_header(request.headers.get("content-type", ""))
    if content_type != b"multipart/form-data" or not options.get(b"boundary"):
        raise InputError("the upload must be multipart/form-data with a file and an entry")
    check_declared_length(request, max_file_bytes)
    receiver = _Receiver(folder, max_file_bytes)
    parser = MultipartParser(options[b"boundary"], receiver.callbacks())  # type: ignore[arg-type]
    total = 0
    try:
        async for chunk in request.stream():
            total += len(chunk)
            if total > max_file_bytes + FORM_OVERHEAD_BYTES:
                raise PayloadTooLarge(
                    f"the request is larger than the upload limit of {max_file_bytes} bytes"
                )
            parser.write(chunk)
        parser.finalize()
    except GearwatchError:
        raise
    except Exception as error:  # python-multipart's parse errors: a malformed body
        raise InputError(f"the upload is not a valid multipart form: {error}") from None
    finally:
        receiver.close()
    return receiver.result
