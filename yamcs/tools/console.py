#!/usr/bin/env python3
"""The operators' console in Yamcs (docs/ground-segment.md, "The console"):

    python3 yamcs/tools/console.py lists     # create or update the shipped parameter lists

scripts/ground-segment.sh runs it at every start, once Yamcs is up: every list of
yamcs/lists/parameter-lists.json (generated from the mission database,
ground/src/mdb/console.rs) is created, or updated when a list of that name exists with
other patterns or description (lists live in the Yamcs archive, which is kept between
starts). Lists of other names (an operator's own) are left alone. Logs in as the
operator (yamcs/etc/users.yaml). The displays and stacks need nothing: Yamcs serves
them from the repository's folders (buckets `displays`, `stacks`, yamcs/etc/yamcs.yaml).
"""

from __future__ import annotations

import json
import os
import sys
import urllib.request
from pathlib import Path

from users import basic_auth

YAMCS = Path(__file__).resolve().parents[1]
LISTS = YAMCS / "lists" / "parameter-lists.json"
URL = os.environ.get("M2_YAMCS_URL", "localhost:8090")
INSTANCE = "m2"


def shipped_lists() -> list[dict]:
    """The parameter lists the repository ships (name, description, patterns)."""
    return json.loads(LISTS.read_text())


def request(method: str, path: str, body: dict | None = None, user: str = "operator"):
    req = urllib.request.Request(
        f"http://{URL}{path}", method=method,
        data=json.dumps(body).encode() if body is not None else None,
        headers={"Content-Type": "application/json", "Authorization": basic_auth(user)})
    with urllib.request.urlopen(req, timeout=10) as r:
        text = r.read()
    return json.loads(text) if text else {}


def yamcs_lists(user: str = "operator") -> list[dict]:
    """The parameter lists Yamcs has (id, name, description, patterns)."""
    return request("GET", f"/api/parameter-lists/{INSTANCE}/lists", user=user).get("lists", [])


def install_lists() -> dict[str, int]:
    """Creates or updates the shipped lists; returns how many were created, updated or
    already as shipped."""
    have = {}
    for l in yamcs_lists():
        have.setdefault(l["name"], l)
    counts = {"created": 0, "updated": 0, "unchanged": 0}
    for want in shipped_lists():
        got = have.get(want["name"])
        if got is None:
            request("POST", f"/api/parameter-lists/{INSTANCE}/lists", want)
            counts["created"] += 1
        elif got.get("patterns", []) != want["patterns"] or got.get("description", "") != want["description"]:
            request("PATCH", f"/api/parameter-lists/{INSTANCE}/lists/{got['id']}", {
                "description": want["description"],
                "patternDefinition": {"patterns": want["patterns"]},
            })
            counts["updated"] += 1
        else:
            counts["unchanged"] += 1
    return counts


def main() -> int:
    if sys.argv[1:] != ["lists"]:
        print(__doc__, file=sys.stderr)
        return 2
    counts = install_lists()
    print("ground-segment: parameter lists " + ", ".join(f"{n} {k}" for k, n in counts.items())
          + f" ({LISTS.relative_to(YAMCS.parent)})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
