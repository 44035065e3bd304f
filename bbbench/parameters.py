"""`@parameters`: the frozen dataclasses that describe a task, with clear errors."""

from __future__ import annotations

import dataclasses
import functools
import numbers
from typing import Any, TypeVar

import numpy as np

T = TypeVar("T", bound=type)


def parameters(cls: T) -> T:
    """A frozen dataclass whose constructor names the accepted parameters on a wrong one.

    Task components (terrain generators, sensor models, command schedules, ...)
    are plain frozen dataclasses; a misspelt keyword would otherwise get Python's
    bare "unexpected keyword argument", without saying what is accepted.
    """
    cls = dataclasses.dataclass(frozen=True)(cls)
    accepted = [field.name for field in dataclasses.fields(cls) if field.init]
    init = cls.__init__

    @functools.wraps(init)
    def __init__(self, *args, **kwargs) -> None:
        unknown = sorted(set(kwargs) - set(accepted))
        if unknown:
            raise TypeError(
                f"{cls.__name__} has no parameter {', '.join(map(repr, unknown))}; "
                f"accepted: {', '.join(accepted) or 'none'}"
            )
        init(self, *args, **kwargs)

    cls.__init__ = __init__
    return cls


def is_real(value: Any) -> bool:
    """Whether `value` is a real number of any type (Python's, numpy's scalars: float32,
    int64, ...), but not a bool, which is a yes or no."""
    return isinstance(value, numbers.Real) and not isinstance(value, bool | np.bool_)
