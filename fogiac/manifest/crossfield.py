"""The checks across fields, run even where some fields are broken, so ``validate`` reports in one round.

pydantic skips a model's ``model_validator(mode="after")`` as soon as one of its fields fails,
and with it every rule of the models above (one bad ``machine`` hides a duplicate node name).
Here each model is rebuilt from the fields that did validate; a broken field becomes a
:class:`_Broken` stand-in that stops any rule touching it, and that rule is reported as
skipped, naming the field it needs. The rules themselves stay where they are, on the models.
"""

from __future__ import annotations

import difflib
import typing
from collections.abc import Iterator
from typing import Annotated, Any

from pydantic import BaseModel, TypeAdapter, ValidationError, WrapValidator
from pydantic.fields import FieldInfo

from fogiac.manifest.problems import FieldProblem, Loc, _parse_path, each_problem, path_str, problem_text


class _Skipped(Exception):
    def __init__(self, field: Loc, *, quiet: bool) -> None:
        super().__init__(field)
        self.field = field
        self.quiet = quiet


class _Broken:
    """A field that failed validation, by its full path: any use of it stops the rule that uses it,
    printing it included (a rule's message never shows the stand-in itself).

    ``quiet``: the field is missing, which its own line already says; the skip says nothing more.
    """

    def __init__(self, field: Loc, *, quiet: bool = False) -> None:
        self._field = field
        self._quiet = quiet

    def _stop(self, *args: object, **kwargs: object) -> typing.NoReturn:
        raise _Skipped(self._field, quiet=self._quiet)

    __getattr__ = __bool__ = __iter__ = __eq__ = __ne__ = __lt__ = __len__ = __contains__ = __hash__ = _stop
    __str__ = __repr__ = __format__ = __int__ = __float__ = __index__ = __add__ = __radd__ = _stop


def _model_of(annotation: Any) -> tuple[type[BaseModel] | None, bool]:
    """(the model an annotation holds, whether as a tuple of them)."""
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return annotation, False
    if typing.get_origin(annotation) is tuple:
        args = typing.get_args(annotation)
        if len(args) == 2 and args[1] is Ellipsis and isinstance(args[0], type) and issubclass(args[0], BaseModel):
            return args[0], True
    return None, False


def _value(annotation: Any, raw: Any, path: Loc, found: list[tuple[Loc, BaseModel]]) -> Any:
    model, many = _model_of(annotation)
    if model is not None and not many and isinstance(raw, dict):
        return _partial(model, raw, path, found)
    if model is not None and many and isinstance(raw, list):
        return tuple(_partial(model, item, path + (i,), found) if isinstance(item, dict) else _Broken(path + (i,))
                     for i, item in enumerate(raw))
    try:
        return TypeAdapter(annotation).validate_python(raw)
    except ValidationError:
        return _Broken(path)


def _widened(info: FieldInfo) -> Any:
    """The field's type with its wrap validators, which widen what it admits (a distribution an installed
    middleware serves): a value the field took is not broken here. Its other constraints stay out, as before."""
    wraps = [m for m in info.metadata if isinstance(m, WrapValidator)]
    return Annotated[(info.annotation, *wraps)] if wraps else info.annotation


def _partial(model: type[BaseModel], raw: dict[str, Any], path: Loc, found: list[tuple[Loc, BaseModel]]) -> BaseModel:
    values: dict[str, Any] = {}
    keys = {info.alias or name: name for name, info in model.model_fields.items()}
    for key, name in keys.items():
        info = model.model_fields[name]
        if key in raw:
            values[name] = _value(_widened(info), raw[key], path + (key,), found)
        elif info.is_required():
            values[name] = _Broken(path + (key,), quiet=True)
    for key in raw:  # a misspelt key ('imag') stands for the field it was meant to be: broken, not absent
        meant = difflib.get_close_matches(str(key), [k for k in keys if k not in raw], n=1, cutoff=0.6)
        if key not in keys and meant:
            values[keys[meant[0]]] = _Broken(path + (str(key),))
    built = model.model_construct(**values)
    found.append((path, built))
    return built


def _rules(model: type[BaseModel]) -> Iterator[Any]:
    for dec in model.__pydantic_decorators__.model_validators.values():
        if dec.info.mode == "after":
            yield dec.func


def cross_field_problems(model: type[BaseModel], data: dict[str, Any]) -> list[tuple[Loc, str]]:
    """Every after-rule of every model in ``data``, run on what validated: (path, problem) each."""
    found: list[tuple[Loc, BaseModel]] = []
    _partial(model, data, (), found)
    out: list[tuple[Loc, str]] = []
    for path, built in found:
        for rule in _rules(type(built)):
            try:
                rule(built)
            except FieldProblem as err:
                for each in each_problem(err):
                    out.append((path + (_parse_path(each.field) if each.field else ()), problem_text(each)))
            except _Skipped as skipped:
                if skipped.quiet:
                    continue
                out.append((path, f"checks across fields skipped: they need {path_str(skipped.field)}, "
                                  "which has a problem"))
            except (TypeError, AttributeError, KeyError, ValueError):
                continue  # a stand-in the rule could not use; the field's own problem is reported
    return out
