"""A node's replicas in the manifest: how many, how a reply names its request, and when the others are asked.

``replicas: N`` runs the node on N hosts of its own; the edge sends each request to every live replica
and hands the robot the first reply to each request (:class:`fogiac.plan.model.Replica`). Which
request a reply answers is ``reply_match``: by default its ``std_msgs/Header`` stamp (ROS practice: a
reply copies its request's header), else a field the node names. The manifest's topics carry no
message types, so a node may state them (``message_types``); a stated type is checked at ``validate``
against :mod:`fogiac.msgtypes` (the message facts the relay and Zenoh read keys with), and an out topic
without one is accepted with a one-line warning (and a line in the plan) that its match is unchecked:
the edge finds out at the first reply.
"""

from __future__ import annotations

import re
import warnings

from pydantic import Field

from fogiac import msgtypes
from fogiac.manifest.fields import _Model
from fogiac.msgtypes import DEFAULT_MATCH as DEFAULT_MATCH  # the field's default, beside its other rules

MAX_REPLICAS = 8
_FIELD_PATH = re.compile(r"^[a-z_][a-z0-9_]*(\.[a-z_][a-z0-9_]*){0,7}$")
_TYPE = re.compile(r"^[A-Za-z][A-Za-z0-9_]*/(msg/)?[A-Z][A-Za-z0-9_]*$")


class MatchUnchecked(UserWarning):
    """A replicated node's out topic with no stated type: its reply match is accepted unchecked."""


class Hedge(_Model):
    """Ask the first replica, and the others only when it has not answered within ``delay_ms``."""

    delay_ms: int = Field(strict=True, ge=1, le=60_000,
                          description="How long the first replica has before the others are asked too, in "
                          "milliseconds (the 'hedged request': less bandwidth than asking all).")


def check_type(name: str) -> str:
    if not _TYPE.match(name):
        raise ValueError(f"{name!r} is not a ROS message type like 'geometry_msgs/PoseArray'")
    return name


def check_match(value: str) -> str:
    if not _FIELD_PATH.match(value):
        raise ValueError(f"{value!r} is not a message field like 'header.stamp' or 'request_id'")
    return value


def match_problems(outputs: tuple[str, ...], types: dict[str, str], match: str) -> list[tuple[str, str]]:
    """(problem, field) for each out topic whose stated type cannot carry ``match`` (a ``header.*`` path, or
    any other field of a type the store knows field by field); a type the store does not know passes."""
    problems = []
    for topic in outputs:
        if topic not in types:
            continue
        try:
            msgtypes.store_for(types[topic]).locate(types[topic], match)
        except msgtypes.UnknownType:
            continue
        except msgtypes.MatchError as err:
            problems.append((f"{topic}: {err}, so replies cannot be matched by {match}; set reply_match to a "
                             "field the reply copies from its request", "reply_match"))
    return problems


def unchecked(node: str, outputs: tuple[str, ...], types: dict[str, str], match: str) -> str | None:
    """The line saying which of a replicated node's out topics have no stated type (its match unchecked)."""
    untyped = [t for t in outputs if t not in types]
    if not untyped or not match.startswith("header."):
        return None
    return f"{node}: replies on {', '.join(untyped)} are matched by {match}, unchecked (no type in message_types)"


def warn_unchecked(line: str) -> None:
    """Said once the manifest is valid (never beside its errors), as a one-line warning."""
    warnings.warn(MatchUnchecked(line), stacklevel=3)
