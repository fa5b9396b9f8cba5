"""Input validation shared by every layer (imports nothing from the package).

Every check raises ``ValueError`` with a message a user can act on: it names
the argument (and, through ``where``, the file or demonstration) and says what
is wrong, e.g. ``"demo 'x.npz': human has NaN at rows 12..15"``.
"""
from __future__ import annotations

import numpy as np


def _prefix(where: str | None) -> str:
    return f"{where}: " if where else ""


def _rows_text(rows: np.ndarray) -> str:
    """Compress sorted row indices into ``"3, 7..9"``."""
    rows = np.unique(rows)
    parts = []
    start = prev = int(rows[0])
    for r in rows[1:]:
        r = int(r)
        if r == prev + 1:
            prev = r
            continue
        parts.append(f"{start}" if start == prev else f"{start}..{prev}")
        start = prev = r
    parts.append(f"{start}" if start == prev else f"{start}..{prev}")
    text = ", ".join(parts[:5])
    return text + (", ..." if len(parts) > 5 else "")


def as_finite_array(x, name: str, *, ndim: int | None = None, shape=None,
                    min_rows: int | None = None, where: str | None = None) -> np.ndarray:
    """Convert ``x`` to a float64 array and validate it.

    Parameters
    ----------
    x : array_like
    name : str
        Name used in error messages.
    ndim : int, optional
        Required number of dimensions.
    shape : tuple, optional
        Required shape; ``None`` entries match any size.
    min_rows : int, optional
        Minimum length of axis 0.
    where : str, optional
        Context prefix for messages (file or demonstration name).
    """
    p = _prefix(where)
    try:
        complex_ = np.iscomplexobj(x)
    except (TypeError, ValueError):  # ragged or not numeric: the conversion below names it
        complex_ = False
    if complex_:
        raise ValueError(f"{p}{name} is complex; give real numbers")
    try:
        a = np.asarray(x, dtype=float)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{p}{name} is not numeric ({exc})") from None
    if ndim is not None and a.ndim != ndim:
        raise ValueError(f"{p}{name} must have {ndim} dimension(s), got shape {a.shape}")
    if shape is not None:
        if a.ndim != len(shape) or any(s is not None and s != d for s, d in zip(shape, a.shape)):
            want = "(" + ", ".join("any" if s is None else str(s) for s in shape) + ")"
            raise ValueError(f"{p}{name} must have shape {want}, got {a.shape}")
    if min_rows is not None and (a.ndim == 0 or a.shape[0] < min_rows):
        n = 0 if a.ndim == 0 else a.shape[0]
        raise ValueError(f"{p}{name} is too short: {n} sample(s), need at least {min_rows}")
    bad = ~np.isfinite(a)
    if bad.any():
        kind = "NaN" if np.isnan(a[bad]).any() else "inf"
        if a.ndim >= 1:
            rows = np.nonzero(bad.reshape(a.shape[0], -1).any(axis=1))[0]
            raise ValueError(f"{p}{name} has {kind} at rows {_rows_text(rows)}")
        raise ValueError(f"{p}{name} is {kind}")
    return a


def check_increasing(t: np.ndarray, name: str = "t", where: str | None = None) -> None:
    """Raise unless ``t`` is strictly increasing."""
    d = np.diff(t)
    if (d <= 0).any():
        i = int(np.nonzero(d <= 0)[0][0])
        raise ValueError(f"{_prefix(where)}{name} is not strictly increasing: "
                         f"{name}[{i}]={t[i]:g} then {name}[{i + 1}]={t[i + 1]:g}")


def check_integer(value, name: str, lo: int, hi: int | None = None) -> int:
    """``value`` as an int in ``[lo, hi]`` (a whole float counts; bool, nan, inf and text do not), else a ValueError naming ``name``."""
    try:
        whole = not isinstance(value, bool) and int(value) == value
    except (TypeError, ValueError, OverflowError):
        whole = False
    if not whole or value < lo or (hi is not None and value > hi):
        bound = f">= {lo}" if hi is None else f"in {lo}..{hi}"
        raise ValueError(f"{name} must be an integer {bound}, got {value!r}")
    return int(value)


def check_fraction(value, name: str = "observed_fraction") -> float:
    """``value`` as a float in (0, 1] (bool and text are refused), else a ValueError naming ``name``."""
    ok = not isinstance(value, (bool, np.bool_, str, bytes)) and np.ndim(value) == 0
    try:
        f = float(value) if ok else float("nan")
    except (TypeError, ValueError):
        f = float("nan")
    if not 0 < f <= 1:
        raise ValueError(f"{name} must be a number in (0, 1], got {value!r}")
    return f


def check_positive(value: float, name: str) -> float:
    value = float(value)
    if not np.isfinite(value) or value <= 0:
        raise ValueError(f"{name} must be a positive finite number, got {value!r}")
    return value


def validated(obj):
    """A copy of a dataclass tree built through the constructors, so every ``__post_init__`` runs.

    Drake's ``yaml_load_typed`` fills a config by setting fields one at a time, which
    skips validation; passing the result through here validates it as if it had
    been built in Python. Lists and dicts are walked; other values are kept.
    """
    import dataclasses

    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        return type(obj)(**{f.name: validated(getattr(obj, f.name)) for f in dataclasses.fields(obj) if f.init})
    if isinstance(obj, list):
        return [validated(x) for x in obj]
    if isinstance(obj, dict):
        return {k: validated(v) for k, v in obj.items()}
    return obj
