"""LALR parsers whose grammar analysis is cached on disk between runs.

Building the LALR tables of the design language and of the expression language takes
about 0.3 s, which every command would pay at start-up. lark can store the analysed
parser and load it back in a few milliseconds; the cache lives in the user's own cache
directory (``$XDG_CACHE_HOME/fgslice``, by default ``~/.cache/fgslice``), never in a shared
temporary directory, and its file name carries a hash of the grammar, the options and the
lark and Python versions, so a changed grammar never loads a stale parser. When the
directory cannot be created or written, the parser is simply built each time.
"""

from __future__ import annotations

import hashlib
import os
import sys
from pathlib import Path

import lark


def cache_dir() -> Path:
    """``$XDG_CACHE_HOME/fgslice`` (``~/.cache/fgslice`` when unset)."""
    base = os.environ.get("XDG_CACHE_HOME", "").strip() or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "fgslice"


def cached_lark(grammar: str, **options) -> lark.Lark:
    """``lark.Lark(grammar, parser="lalr", **options)``, its analysis cached on disk."""
    key = repr((grammar, sorted(options.items()), lark.__version__, sys.version_info[:2]))
    digest = hashlib.sha256(key.encode()).hexdigest()[:24]
    directory = cache_dir()
    try:
        directory.mkdir(parents=True, exist_ok=True)
    except OSError:
        return lark.Lark(grammar, parser="lalr", **options)
    return lark.Lark(grammar, parser="lalr", cache=str(directory / f"lark-{digest}.cache"), **options)
