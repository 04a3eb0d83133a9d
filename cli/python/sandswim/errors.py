"""The one exception the client raises: the daemon's refusal, or why the daemon could not be asked.

The daemon answers every refusal with an RFC 9457 problem document (application/problem+json)
naming the field at fault; SandswimError carries it unchanged. The client checks nothing the
daemon checks (one source of truth): a bad sweep reaches the daemon and comes back as

    SandswimError: base.A: must be > 0 m, got -0.03
"""

from __future__ import annotations

from typing import Any, Mapping, Optional


class SandswimError(Exception):
    """A request the daemon refused (status 4xx/5xx), or one that did not reach it (status None).

    Attributes:
        status: the HTTP status, or None when no answer came (connection refused, time-out).
        field: the problem document's `field`: which input was wrong ("base.A", "Authorization").
        reason: what was wrong with it, as the daemon said it ("must be > 0 m, got -0.03").
        problem: the whole problem document (type, title, status, detail, field, ...), or {}.
    """

    def __init__(self, reason: str, *, status: Optional[int] = None, field: str = "",
                 problem: Optional[Mapping[str, Any]] = None) -> None:
        self.status = status
        self.field = field
        self.reason = reason
        self.problem = dict(problem or {})
        super().__init__(self._text())

    def _text(self) -> str:
        # The daemon's detail already opens with its field ("base.A: must be ..."): not twice.
        if not self.field or self.reason.startswith(self.field + ":"):
            return self.reason
        return f"{self.field}: {self.reason}"

    @classmethod
    def from_response(cls, status: int, body: bytes, content_type: str, what: str) -> "SandswimError":
        """The error an HTTP answer `status` with `body` stands for; `what` is "GET /api/v1/...".

        A problem document gives its field and detail; any other body is quoted, shortened.
        """
        problem: dict[str, Any] = {}
        if "json" in content_type:
            try:
                import json

                parsed = json.loads(body.decode("utf-8"))
                if isinstance(parsed, dict):
                    problem = parsed
            except (ValueError, UnicodeDecodeError):
                pass
        field = str(problem.get("field") or "")
        detail = str(problem.get("detail") or problem.get("title") or "")
        if not detail:
            text = body.decode("utf-8", "replace").strip()
            detail = f"{what} answered {status}" + (f": {text[:200]}" if text else "")
        if status == 401:
            detail += (" (give Client(url, token=...) or token_file=DATA/token, the daemon's --data directory's"
                       " token file, or set SANDSWIM_TOKEN)")
        return cls(detail, status=status, field=field, problem=problem)
