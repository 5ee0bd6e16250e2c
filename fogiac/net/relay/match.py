"""How a reply names its request, read off a ROS 1 serialized message without deserializing it. Pure.

The facts (where a field is, what it is) are :data:`fogiac.msgtypes.ROS1`'s, the store validation
checks a stated type with. ``header.stamp`` (the default, ROS practice: a reply carries its request's
``std_msgs/Header`` stamp) is bytes 4..12 of a message whose first field is its Header (uint32 seq,
time stamp, string frame_id), whatever the type. Any other dotted path (``id``, ``request.uuid``,
``header.frame_id``...) needs the topic's message definition, which a publisher sends in its TCPROS
header: the store adds it and finds the field, skipping every field before it (strings and arrays by
their length prefixes), so the key is the field's own bytes, whatever its type. A path that names no
field is an error; a message too short for it has no key. A definition comes from a publisher (over a
replica's link, a replica's): one fogiac will not read (:class:`~fogiac.msgtypes.DefinitionError`) is a
:class:`BadDefinition`, which refuses that publisher, where a field its type lacks only leaves it keyless.
"""

from __future__ import annotations

from fogiac import msgtypes
from fogiac.msgtypes import DEFAULT_MATCH as DEFAULT_MATCH
from fogiac.msgtypes import Key as Key
from fogiac.msgtypes import KeyOf as KeyOf
from fogiac.net.relay.errors import RelayError


class BadDefinition(RelayError):
    """A publisher's message definition that is malformed, self-referential, nested too deep or too big."""


def key_reader(match: str, type_name: str = "*", definition: str = "") -> KeyOf:
    """A function from a serialized message to its key (None: the message is too short to have one)."""
    try:
        if match == DEFAULT_MATCH:  # every reply is taken to begin with a Header (validate checks stated types)
            return msgtypes.ROS1.key_reader(msgtypes.HEADER, match)
        if not [p for p in match.split(".") if p]:
            raise RelayError(f"match {match!r} names no field")
        if not definition:
            raise RelayError(f"match {match!r}: the publisher of {type_name} sent no message definition")
        return msgtypes.ROS1.with_definition(definition, type_name).key_reader(type_name, match)
    except msgtypes.DefinitionError as err:
        raise BadDefinition(str(err)) from None
    except msgtypes.MatchError as err:
        raise RelayError(str(err)) from None
