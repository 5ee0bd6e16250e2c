"""The manifest's field types and checks, shared by its blocks: names, topics, paths, addresses,
the ROS distribution and the provider (each admitting a plug-in's), and how a block asks its target's
``cloud:`` variant (:func:`_sizing`)."""

from __future__ import annotations

import ipaddress
import re
from collections.abc import Iterable
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Literal

from pydantic import (
    AfterValidator,
    BaseModel,
    ConfigDict,
    Field,
    ValidationError,
    ValidationInfo,
    ValidatorFunctionWrapHandler,
    WrapValidator,
    field_validator,
)

from fogiac import middlewares
from fogiac.manifest.clouds import CloudVariant, providers, sizing

_DNS_NAME = re.compile(r"^[a-z]([a-z0-9-]{0,38}[a-z0-9])?$")


_TOPIC = re.compile(r"^/[A-Za-z][A-Za-z0-9_/]*$")


_ENV_NAME = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")


# An OCI image reference: [registry[:port]/]path[:tag][@digest], lowercase path components.
_IMAGE_REF = re.compile(
    r"^(?:[A-Za-z0-9](?:[A-Za-z0-9.-]*[A-Za-z0-9])?(?::[0-9]+)?/)?"
    r"[a-z0-9]+(?:(?:[._]|__|-+)[a-z0-9]+)*(?:/[a-z0-9]+(?:(?:[._]|__|-+)[a-z0-9]+)*)*"
    r"(?::[A-Za-z0-9_][A-Za-z0-9_.-]{0,127})?(?:@sha256:[0-9a-f]{64})?$"
)


# ssh_from may cover at most a /8 (16.7 M addresses) in all: the largest block one organisation
# holds (the legacy /8s); anything wider is not "my network" but a share of the whole internet,
# and /1 pairs would otherwise slip past a check for 0.0.0.0/0 alone.
SSH_FROM_MAX_PREFIX = 8


_USER = re.compile(r"^[a-z_][a-z0-9_-]{0,31}$")  # POSIX user names as useradd takes them


_HOST_LABEL = re.compile(r"^(?!-)[A-Za-z0-9-]{1,63}(?<!-)$")


def ssh_from_problem(nets: Iterable[ipaddress.IPv4Network]) -> str | None:
    """Why these CIDRs are too wide to open SSH (and the relay) to, or None."""
    given = list(nets)
    covered = sum(n.num_addresses for n in ipaddress.collapse_addresses(given))
    if covered > 2 ** (32 - SSH_FROM_MAX_PREFIX):
        return (f"{', '.join(str(n) for n in given)} cover {covered} addresses, more than a "
                f"/{SSH_FROM_MAX_PREFIX} ({2 ** (32 - SSH_FROM_MAX_PREFIX)}); name your own network")
    return None


def _sizing(info: ValidationInfo | None) -> CloudVariant:
    """The ``cloud:`` variant that names the machines: the manifest's provider's, which
    :func:`parse_manifest` passes as context; without one (a model built in code) or with one that names
    no variant, the default's (:func:`~fogiac.manifest.clouds.sizing`)."""
    context = info.context if info is not None else None
    return sizing(context.get("provider") if isinstance(context, dict) else None)


def _no_control(value: Path) -> Path:
    if any(ord(c) < 32 or ord(c) == 127 for c in str(value)):
        raise ValueError(f"{str(value)!r} contains a control character")
    return value


PlainPath = Annotated[Path, AfterValidator(_no_control)]


def _user(value: str) -> str:
    if not _USER.match(value):
        raise ValueError(f"{value!r} is not a user name (lowercase letters, digits, '_', '-', up to 32)")
    return value


def _address(value: str) -> str:
    try:
        ipaddress.ip_address(value)
        return value
    except ValueError:
        pass
    if len(value) <= 253 and all(_HOST_LABEL.match(label) for label in value.split(".")):
        return value
    raise ValueError(f"{value!r} is not an IP address or host name (letters, digits, '-', dots)")


Compression = Literal["none", "zstd", "lz4"]


class _Model(BaseModel):
    model_config = ConfigDict(frozen=True, extra="forbid", populate_by_name=True)


_SECRET_REF = re.compile(r"^(env:[A-Za-z_][A-Za-z0-9_]*|file:[^\x00-\x1f\x7f]+)$")


class Secret(_Model):
    """An env value fogiac never holds: named here, read at ``up`` and written only on the host (0600).

    ``env:NAME`` is the operator's environment variable NAME; ``file:PATH`` the first line of a file
    on the operator's machine (relative to the manifest, or ``~/...``). Plans, the recorded state and
    pull-request comments show the reference, never the value."""

    secret: str = Field(description="Where the value is read at `up`: env:NAME (the operator's environment) "
                        "or file:PATH (a file on the operator's machine).")

    @field_validator("secret")
    @classmethod
    def _ref(cls, value: str) -> str:
        if not _SECRET_REF.match(value):
            raise ValueError(f"{value!r} is not a secret reference: env:NAME or file:PATH")
        return value


def _topic(value: str) -> str:
    if not _TOPIC.match(value) or "//" in value or value.endswith("/"):
        raise ValueError(f"{value!r} is not a ROS topic name (absolute, like '/camera/depth')")
    return value


Topic = Annotated[str, Field(description="An absolute ROS topic name, e.g. /camera/depth")]


def _dns_name(value: str) -> str:
    if not _DNS_NAME.match(value):
        raise ValueError(f"{value!r} is not DNS-safe (lowercase letters, digits, '-', up to 40)")
    return value


DnsName = Annotated[str, AfterValidator(_dns_name)]


def _served(value: object, handler: ValidatorFunctionWrapHandler) -> object:
    """A distribution an installed middleware serves (entry point group ``fogiac.middlewares``); the
    middlewares are asked only for a name that is not fogiac's own, so ``validate`` stays fast."""
    try:
        return handler(value)
    except ValidationError:
        if isinstance(value, str) and value in middlewares.distros():
            return value
        raise


def _contributed(value: object, handler: ValidatorFunctionWrapHandler) -> object:
    """A provider an installed package contributes (entry point group ``fogiac.clouds``); the
    distributions are read only for a name that is not built in, so ``validate`` stays fast."""
    try:
        return handler(value)
    except ValidationError:
        if isinstance(value, str) and value in providers():
            return value
        raise


if TYPE_CHECKING:
    Distro = str
    Provider = str
else:  # fogiac's own middlewares' distributions, and (_served) one another installed middleware serves;
    # on the type, not the field, so the checks across fields (crossfield.py) admit it too
    Distro = Annotated[Literal["noetic", "humble", "jazzy", "kilted"], WrapValidator(_served)]
    # fogiac's own targets' ``cloud:`` variants, and (_contributed) another installed package's
    Provider = Annotated[Literal[providers(own=True)], WrapValidator(_contributed)]


