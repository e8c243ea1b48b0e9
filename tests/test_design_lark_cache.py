"""The on-disk cache of analysed LALR parsers (design/lark_cache.py)."""

from __future__ import annotations

import os

import pytest

from fgslice.design.lark_cache import cache_dir, cached_lark

GRAMMAR = r"""
start: sum
sum: NUMBER ("+" NUMBER)*
NUMBER: /\d+/
%ignore " "
"""


def test_cache_dir_follows_xdg_cache_home(tmp_path, monkeypatch):
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    assert cache_dir() == tmp_path / "fgslice"


def test_second_parser_loads_from_the_cache_and_parses_the_same(tmp_path, monkeypatch):
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    first = cached_lark(GRAMMAR, propagate_positions=True)
    files = list((tmp_path / "fgslice").glob("lark-*.cache"))
    assert len(files) == 1 and files[0].stat().st_size > 0
    stamp = files[0].stat().st_mtime_ns
    second = cached_lark(GRAMMAR, propagate_positions=True)
    assert files[0].stat().st_mtime_ns == stamp
    assert second.parse("1 + 22 + 333") == first.parse("1 + 22 + 333")


def test_another_grammar_or_options_get_their_own_cache_file(tmp_path, monkeypatch):
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    cached_lark(GRAMMAR)
    cached_lark(GRAMMAR, propagate_positions=True)
    cached_lark(GRAMMAR.replace(r"/\d+/", r"/[0-9]+/"))
    assert len(list((tmp_path / "fgslice").glob("lark-*.cache"))) == 3


@pytest.mark.skipif(os.geteuid() == 0 if hasattr(os, "geteuid") else True, reason="root ignores permissions")
def test_unwritable_cache_directory_still_gives_a_parser(tmp_path, monkeypatch):
    tmp_path.chmod(0o500)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "sub"))
    try:
        assert cached_lark(GRAMMAR).parse("4 + 5") is not None
    finally:
        tmp_path.chmod(0o700)


def test_cache_directory_that_is_a_file_still_gives_a_parser(tmp_path, monkeypatch):
    (tmp_path / "fgslice").write_text("not a directory")
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    assert cached_lark(GRAMMAR).parse("4 + 5") is not None


def test_corrupt_cache_file_is_rebuilt(tmp_path, monkeypatch):
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    cached_lark(GRAMMAR)
    (cache,) = (tmp_path / "fgslice").glob("lark-*.cache")
    cache.write_bytes(b"garbage\x00\x01")
    assert cached_lark(GRAMMAR).parse("7 + 8") is not None
    assert cache.read_bytes() != b"garbage\x00\x01"
