"""Render the files in ``templates/``: the one place Jinja2 is used, always StrictUndefined.

Rendering is pure (name and context in, text out); writing the result is the caller's step.
"""

from __future__ import annotations

import shlex
from functools import lru_cache
from typing import Any

import jinja2

from fogiac.resources import templates_dir


@lru_cache(maxsize=1)
def _environment() -> jinja2.Environment:
    env = jinja2.Environment(
        loader=jinja2.FileSystemLoader(str(templates_dir())),
        undefined=jinja2.StrictUndefined,
        keep_trailing_newline=True,
        trim_blocks=True,
        lstrip_blocks=True,
        autoescape=False,
    )
    env.filters["shquote"] = lambda value: shlex.quote(str(value))
    return env


def render(name: str, /, **context: Any) -> str:
    """Render ``templates/<name>`` with ``context``; a missing variable is an error, not ''."""
    return _environment().get_template(name).render(**context)
