"""The web server's settings: one typed class that fails fast.

``pydantic-settings`` is not a dependency, so :meth:`WebSettings.from_env` reads the few environment
variables itself (``SUNBENCH_HOST``, ``SUNBENCH_PORT``, ``SUNBENCH_PUBLIC_READ``) and takes the token from
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
    """

    model_config = ConfigDict(frozen=True, extra="forbid")

    host: str = "127.0.0.1"
    port: int = Field(8000, ge=1, le=65535)
    public_read: bool = False
    token: str = Field(min_length=16)
    sse_keepalive_s: float = Field(15.0, gt=0)

    @field_validator("token")
    @classmethod
    def _token_is_one_word(cls, v: str) -> str:
        if v != v.strip() or any(c.isspace() for c in v):
            raise ValueError("the token must not contain whitespace (it travels in an Authorization header)")
        return v

    @classmethod
    def from_env(cls, *, config_dir=None, **overrides) -> WebSettings:
        """Settings from the environment and the token file; keyword arguments win over both."""
        from .security import load_or_create_token

        values: dict = {}
        if "SUNBENCH_HOST" in os.environ:
            values["host"] = os.environ["SUNBENCH_HOST"]
        if "SUNBENCH_PORT" in os.environ:
            values["port"] = os.environ["SUNBENCH_PORT"]
        if "SUNBENCH_PUBLIC_READ" in os.environ:
            values["public_read"] = os.environ["SUNBENCH_PUBLIC_READ"].strip().lower() in ("1", "true", "yes", "on")
        if "token" not in overrides:
            values["token"], _ = load_or_create_token(config_dir)
        return cls.model_validate({**values, **overrides})
