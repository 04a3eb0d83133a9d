"""Where the client finds the daemon's bearer token: the CLI's rule (platform/token.h).

In this order: the token given to Client; the file given as token_file (its contents, surrounding
whitespace trimmed; a missing, unreadable or empty file is an error); $SANDSWIM_TOKEN (trimmed);
else, only when the daemon's URL names a loopback host so that the token never goes to another
machine, ./var/data/token (the file a daemon started with its default --data made) when it
exists. None when no token is found (a daemon started with --no-token needs none).
"""

from __future__ import annotations

import ipaddress
import os
from typing import Mapping, Optional
from urllib.parse import urlsplit

from .errors import SandswimError

DEFAULT_SERVER = "http://127.0.0.1:8640"  # platform/http_client.h kDefaultServer
DEFAULT_TOKEN_FILE = os.path.join(".", "var", "data", "token")  # DataDir(kDefaultDataDir).Token() (platform/data_dir.h)


def is_loopback_host(host: str) -> bool:
    """True for "localhost", 127.0.0.0/8 and ::1 (brackets allowed), as platform/token.h's."""
    host = host[1:-1] if host.startswith("[") and host.endswith("]") else host
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


def _read_token_file(path: str, field: str) -> str:
    try:
        with open(path, encoding="utf-8") as f:
            token = f.read().strip()
    except OSError as e:
        raise SandswimError(f"cannot read the token file {path}: {e.strerror}", field=field) from None
    if not token:
        raise SandswimError(f"the token file {path} is empty", field=field)
    return token


def find_token(url: str, token: Optional[str] = None, token_file: Optional[str] = None,
               environ: Optional[Mapping[str, str]] = None,
               default_file: str = DEFAULT_TOKEN_FILE) -> Optional[str]:
    """The token for the daemon at `url` by the rule above; `environ` and `default_file` for tests."""
    if token:
        return token.strip()
    if token_file:
        return _read_token_file(token_file, "token_file")
    env = os.environ if environ is None else environ
    from_env = (env.get("SANDSWIM_TOKEN") or "").strip()
    if from_env:
        return from_env
    host = urlsplit(url).hostname or ""
    if not is_loopback_host(host) or not os.path.exists(default_file):
        return None
    return _read_token_file(default_file, "token_file")
