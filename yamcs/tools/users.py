#!/usr/bin/env python3
"""The local demonstration users of the M2 Yamcs (yamcs/etc/users.yaml, the one place
their passwords are written), for the ground segment's scripts and tests:

    python3 yamcs/tools/users.py gateway     # prints gateway:PASSWORD (for a URL)

From Python: `credentials("operator")` (yamcs-client), `basic_auth("observer")` (an
HTTP Authorization header value), `access_token("observer", url)` (Yamcs /auth/token).
"""

from __future__ import annotations

import base64
import json
import sys
import urllib.parse
import urllib.request
from pathlib import Path

import yaml

USERS = Path(__file__).resolve().parents[1] / "etc" / "users.yaml"


def password(user: str) -> str:
    users = yaml.safe_load(USERS.read_text())
    if user not in users:
        raise KeyError(f"{user}: not a user of {USERS} ({sorted(users)})")
    return users[user]["password"]


def credentials(user: str):
    from yamcs.client import Credentials
    return Credentials(username=user, password=password(user))


def basic_auth(user: str) -> str:
    return "Basic " + base64.b64encode(f"{user}:{password(user)}".encode()).decode()


def access_token(user: str, url: str) -> dict:
    """Yamcs' answer to a password login (access_token, refresh_token, expires_in)."""
    body = urllib.parse.urlencode(
        {"grant_type": "password", "username": user, "password": password(user)}).encode()
    return json.load(urllib.request.urlopen(f"http://{url}/auth/token", data=body, timeout=10))


if __name__ == "__main__":
    if len(sys.argv) != 2:
        print(__doc__, file=sys.stderr)
        sys.exit(2)
    print(f"{sys.argv[1]}:{password(sys.argv[1])}")
