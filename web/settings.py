"""The web server's settings: one typed class that fails fast.

``pydantic-settings`` is not a dependency, so :meth:`WebSettings.from_env` reads the few environment
variables itself (``SUNBENCH_HOST``, ``SUNBENCH_PORT``, ``SUNBENCH_PUBLIC_READ``, ``SUNBENCH_ALLOWED_HOSTS``:
comma separated) and takes the token from
:func:`web.security.load_or_create_token`.
"""

from __future__ import annotations

import os

from pydantic import BaseModel, ConfigDict, Field, field_validator


class WebSettings(BaseModel):
    """Where the API listens and who may use it.

    Parameters
    ----------
    host : str
        Interface to bind; loopback by default, so the bench is not on the network unless asked.
    port : int
    public_read : bool
        True lets anyone who reaches the server read status and results without the token; commands
        always need it.
    token : str
        The bearer token every command (and every read unless `public_read`) must present.
    sse_keepalive_s : float
        Idle time after which the event stream sends a keep-alive comment [s]. The stream never polls: it
        sleeps until an event, this timeout or shutdown.
    allowed_hosts : tuple of str
        Names the server answers to besides 127.0.0.1, localhost, [::1] and `host` (any other ``Host`` header
        gets 400: see :mod:`web.guard`, against DNS rebinding). A name the bench PC has on a lab network goes
        here; the tests' in-process client, whose requests say ``Host: testserver``, adds that one.
    max_body_bytes : int
        Largest request body taken [bytes]; a larger one gets 413 before it is parsed.
    field_max_body_bytes : int
        Largest request body taken under ``/api/field/`` [bytes] (4 MiB by default), instead of `max_body_bytes`:
        a field CSV is posted whole, and a 2-hour track at 1 Hz (~7200 rows) is ~600 KB. A larger one gets 413
        before it is parsed, as any other.
    """

    model_config = ConfigDict(frozen=True, extra="forbid")

    host: str = "127.0.0.1"
    port: int = Field(8000, ge=1, le=65535)
    public_read: bool = False
    token: str = Field(min_length=16)
    sse_keepalive_s: float = Field(15.0, gt=0)
    allowed_hosts: tuple[str, ...] = ()
    max_body_bytes: int = Field(64 * 1024, ge=1024, le=16 * 1024 * 1024)
    field_max_body_bytes: int = Field(4 * 1024 * 1024, ge=1024, le=64 * 1024 * 1024)

    @field_validator("token")
    @classmethod
    def _token_is_one_word(cls, v: str) -> str:
        if v != v.strip() or any(c.isspace() for c in v):
            raise ValueError("the token must not contain whitespace (it travels in an Authorization header)")
        return v

    @field_validator("allowed_hosts")
    @classmethod
    def _host_names(cls, v: tuple[str, ...]) -> tuple[str, ...]:
        for name in v:
            literal = name.startswith("[") and name.endswith("]")  # an IPv6 address, as a Host header has it
            bare = name[1:-1] if literal else name
            if not bare or any(c.isspace() or c in "/@" for c in bare) or (":" in bare and not literal):
                raise ValueError(f"{name!r} is not a host name (give the name alone, without scheme or port)")
        return tuple(name.lower() for name in v)

    @classmethod
    def from_env(cls, *, config_dir=None, **overrides) -> WebSettings:
        """Settings from the environment and the token file; keyword arguments win over both."""
        from .security import load_or_create_token

        values: dict = {}
        if "SUNBENCH_HOST" in os.environ:
            values["host"] = os.environ["SUNBENCH_HOST"]
        if "SUNBENCH_PORT" in os.environ:
            values["port"] = os.environ["SUNBENCH_PORT"]
        if os.environ.get("SUNBENCH_ALLOWED_HOSTS"):
            values["allowed_hosts"] = tuple(h.strip() for h in os.environ["SUNBENCH_ALLOWED_HOSTS"].split(",")
                                            if h.strip())
        if "SUNBENCH_PUBLIC_READ" in os.environ:
            values["public_read"] = os.environ["SUNBENCH_PUBLIC_READ"].strip().lower() in ("1", "true", "yes", "on")
        if "token" not in overrides:
            values["token"], _ = load_or_create_token(config_dir)
        return cls.model_validate({**values, **overrides})
