"""A bounded cache entry write that is safe while other threads read and write the same cache."""
from __future__ import annotations

from collections import OrderedDict


def put_bounded(cache: OrderedDict, key, value, limit: int):
    """``cache[key] = value``, first evicting the oldest entry if ``cache`` holds ``limit`` or more; returns ``value``.

    ``OrderedDict.popitem`` is one step under the GIL: the eviction never iterates a dict
    another thread is changing ("dictionary changed size during iteration"), and an
    entry another thread evicted first is not an error. Readers should read an entry
    once (``cache.get``) and use what they read.
    """
    if len(cache) >= limit:
        try:
            cache.popitem(last=False)
        except KeyError:  # another thread emptied it
            pass
    cache[key] = value
    return value
