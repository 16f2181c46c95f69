"""Findings kept for the process: searched once a key, the least recently asked for dropped."""

from __future__ import annotations

from spikegs import found_once as memo


def test_a_key_is_searched_once_while_among_the_latest(monkeypatch):
    monkeypatch.setattr(memo, "KEPT", 2)
    searched = []

    def ask(key: bytes) -> str:
        return memo.found_once(key, lambda: searched.append(key) or key.decode())

    assert [ask(b"a"), ask(b"b"), ask(b"a")] == ["a", "b", "a"] and searched == [b"a", b"b"]
    ask(b"c")  # drops b, asked for before a
    assert ask(b"a") == "a" and searched == [b"a", b"b", b"c"]
    assert ask(b"b") == "b" and searched == [b"a", b"b", b"c", b"b"]
