"""Start LocalStack (``python localstack_main.py``, in LocalStack's own venv) with one Python 3.12 behaviour
backported: ``uuid.uuid5`` taking ``bytes`` as the name.

LocalStack 4.13.1's KMS names a key's material with ``uuid5(key_id, key_material)`` (bytes), which Python
3.12 accepts and 3.11 refuses (``TypeError: encoding without a string argument``): every ``CreateKey`` of
a symmetric key fails with an InternalError. The pinned LocalStack is the last that runs on 3.11, so the
emulator gets the newer ``uuid5`` here, as 3.12 defines it (a str name is encoded as UTF-8, bytes are used
as they are); nothing else changes.
"""

from __future__ import annotations

import hashlib
import runpy
import sys
import uuid
from pathlib import Path


def _uuid5(namespace: uuid.UUID, name: str | bytes) -> uuid.UUID:
    data = name.encode("utf-8") if isinstance(name, str) else bytes(name)
    digest = hashlib.sha1(namespace.bytes + data, usedforsecurity=False).digest()
    return uuid.UUID(bytes=digest[:16], version=5)


if __name__ == "__main__":
    here = str(Path(__file__).resolve().parent)
    sys.path[:] = [p for p in sys.path if p and str(Path(p).resolve()) != here]  # the tests' modules stay out
    uuid.uuid5 = _uuid5
    runpy.run_module("localstack.runtime.main", run_name="__main__", alter_sys=True)
