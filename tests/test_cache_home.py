"""The user's cache folder (cache_home.py): where it lies, none where no home is known, and
writes into it that fail quietly."""

from pathlib import Path

from spikegs.cache_home import cache_home, write_cached


def test_the_cache_lies_in_xdg_cache_home_where_absolute_else_in_the_home(tmp_path, monkeypatch):
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert cache_home() == tmp_path / "xdg" / "spikegs"
    monkeypatch.setattr(Path, "home", lambda: tmp_path / "home")
    for relative in ("cache", ""):  # the XDG spec: a relative path is ignored, an empty one unset
        monkeypatch.setenv("XDG_CACHE_HOME", relative)
        assert cache_home() == tmp_path / "home" / ".cache" / "spikegs"


def test_no_home_directory_is_no_cache(monkeypatch):
    """No $HOME and no passwd entry (a container's nobody): no cache, where Path.home raised;
    SIM's user cache is none either (its dataset's folder or a retraining then)."""
    from spikegs.sim_train import user_cache

    def homeless():
        raise RuntimeError("Could not determine home directory.")

    monkeypatch.delenv("XDG_CACHE_HOME", raising=False)
    monkeypatch.setattr(Path, "home", homeless)
    assert cache_home() is None and user_cache("sim.pt", "0123456789abcdef0123") is None


def test_a_cache_that_cannot_be_written_is_skipped(tmp_path):
    """A write into the cache where its folder cannot be made (here a file is in the way) is
    skipped: the next command works it out again."""
    (tmp_path / "file").write_text("")
    write_cached(tmp_path / "file" / "flicker" / "x.json", "{}")
    write_cached(tmp_path / "ok" / "flicker" / "x.json", "{}")
    assert (tmp_path / "ok" / "flicker" / "x.json").read_text() == "{}"
