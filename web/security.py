"""The API token: where it lives, and the dependencies that demand it.

The token is a random string stored in ``$XDG_CONFIG_HOME/sunbench/token`` (``~/.config/sunbench/token``
by default), created at first start, readable by its owner only. Clients send it as
``Authorization: Bearer <token>``.
"""

from __future__ import annotations

import os
import secrets
import stat
from pathlib import Path
from typing import Annotated

from fastapi import Depends, HTTPException, Query, Request, status
from fastapi.security import HTTPAuthorizationCredentials, HTTPBearer

from .settings import WebSettings

TOKEN_FILE = "token"


def default_config_dir() -> Path:
    """``$XDG_CONFIG_HOME/sunbench``, or ``~/.config/sunbench`` when the variable is unset or empty."""
    base = os.environ.get("XDG_CONFIG_HOME") or str(Path.home() / ".config")
    return Path(base) / "sunbench"


def load_or_create_token(config_dir=None) -> tuple[str, bool]:
    """Read the token, or create it (mode 0600) when there is none.

    Parameters
    ----------
    config_dir : path-like, optional
        Folder of the token file; :func:`default_config_dir` by default.

    Returns
    -------
    token : str
    created : bool
        True when this call wrote a new token (the server tells the operator where to find it).
    """
    folder = Path(config_dir) if config_dir is not None else default_config_dir()
    path = folder / TOKEN_FILE
    if path.exists():
        token = path.read_text().strip()
        if token:
            if stat.S_IMODE(path.stat().st_mode) & 0o077:
                path.chmod(0o600)  # a token others can read is no secret; tighten rather than refuse
            return token, False
    folder.mkdir(parents=True, exist_ok=True, mode=0o700)
    token = secrets.token_urlsafe(32)
    tmp = path.with_name(f".{TOKEN_FILE}.{os.getpid()}")
    # created 0600 from the start (no window where the umask's mode applies), then renamed into place
    fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
    with os.fdopen(fd, "w") as fh:
        fh.write(token + "\n")
    os.replace(tmp, path)
    return token, True


_bearer = HTTPBearer(auto_error=False, description="The token from ~/.config/sunbench/token")
_CredentialsDep = Annotated[HTTPAuthorizationCredentials | None, Depends(_bearer)]


# async although they never wait: FastAPI runs a plain `def` dependency in its thread pool, a hop per
# request that costs more than the check (see web/deps.py)
async def _settings(request: Request) -> WebSettings:
    return request.app.state.settings


def _check(credentials: HTTPAuthorizationCredentials | None, settings: WebSettings) -> None:
    if credentials is None:
        raise HTTPException(status.HTTP_401_UNAUTHORIZED,
                            "missing token: send 'Authorization: Bearer <token>' (the token is in "
                            "~/.config/sunbench/token on the bench computer)",
                            headers={"WWW-Authenticate": "Bearer"})
    # constant time, so the answer's timing tells nothing about how much of a guess was right
    if not secrets.compare_digest(credentials.credentials.encode(), settings.token.encode()):
        raise HTTPException(status.HTTP_401_UNAUTHORIZED, "invalid token",
                            headers={"WWW-Authenticate": "Bearer"})


async def require_token(credentials: _CredentialsDep, settings: Annotated[WebSettings, Depends(_settings)]) -> None:
    """Commands: always need the token."""
    _check(credentials, settings)


async def require_read(credentials: _CredentialsDep, settings: Annotated[WebSettings, Depends(_settings)]) -> None:
    """Reads: need the token unless the server runs with ``public_read``."""
    if not settings.public_read:
        _check(credentials, settings)


async def require_read_stream(credentials: _CredentialsDep, settings: Annotated[WebSettings, Depends(_settings)],
                        token: Annotated[str | None, Query(description="The token, for clients that cannot send "
                                                                       "headers (a browser's EventSource)")] = None
                        ) -> None:
    """Reads of the event stream: as :func:`require_read`, but the token may also come as ``?token=``, since
    a browser's ``EventSource`` cannot send an Authorization header. The header wins when both are sent."""
    if credentials is None and token is not None:
        credentials = HTTPAuthorizationCredentials(scheme="Bearer", credentials=token)
    await require_read(credentials, settings)
