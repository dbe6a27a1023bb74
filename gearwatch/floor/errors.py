"""One error hierarchy for the whole application.

The service maps these to HTTP status codes in one place (``service.errors``);
the command line prints ``str(error)`` on one line and exits non-zero. The pure
numerical core (:mod:`dsp`, :mod:`physics`) raises plain ``ValueError``
subclasses of its own and knows nothing of this module.
"""

from __future__ import annotations


class GearwatchError(Exception):
    """Base of every error gearwatch raises on purpose."""

    http_status = 500
    code = "internal_error"
    exit_code = 2
    """The command line's exit status for this error."""


class InputError(GearwatchError):
    """The caller gave something gearwatch cannot use (bad file, bad manifest, bad parameter)."""

    http_status = 422
    code = "invalid_input"


class ManifestError(InputError):
    """A campaign manifest is missing a key, has an unknown key, a wrong type or a missing file."""

    code = "invalid_manifest"


class RecordFormatError(InputError):
    """A record file cannot be read: truncated, corrupt, wrong format, channel not found."""

    code = "invalid_record"


class RecordRejected(InputError):
    """A record was read but fails the quality checks (tach, speed, revolutions, NaN, clipping).

    Rejected records are stored with ``status='rejected'`` and this reason; they never raise alarms.
    """

    code = "record_rejected"


class NotFound(GearwatchError):
    http_status = 404
    code = "not_found"


class Conflict(GearwatchError):
    http_status = 409
    code = "conflict"


class DuplicateRecord(Conflict):
    """The same content is already stored in the campaign. Raised when a concurrent ingestion
    of the same file won the insert while this one was analysing: the caller rolls back and
    runs again, which finds the stored record (outcome ``unchanged``)."""


class Unauthorized(GearwatchError):
    http_status = 401
    code = "unauthorized"


class Forbidden(GearwatchError):
    http_status = 403
    code = "forbidden"


class ServiceUnavailable(GearwatchError):
    """A service gearwatch depends on (database, message broker) cannot be reached right now;
    nothing was half-done, so the same request or command can simply be repeated.

    The REST API answers 503 with ``Retry-After``; the command line exits 75 (EX_TEMPFAIL)."""

    http_status = 503
    code = "service_unavailable"
    retry_after_seconds = 30
    exit_code = 75


class DatabaseUnavailable(ServiceUnavailable):
    code = "database_unavailable"


class BrokerUnavailable(ServiceUnavailable):
    code = "broker_unavailable"
