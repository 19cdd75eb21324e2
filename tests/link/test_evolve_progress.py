"""`pac-host evolve` shows its progress on stderr: a line per punctuation, none with --quiet."""

from __future__ import annotations

from .conftest import SMALL, invoke


def test_evolve_prints_a_line_per_punctuation(tmp_path):
    res = invoke("evolve", "--out", str(tmp_path / "a"), "--generations", "20", *SMALL)
    assert res.exit_code == 0, res.output
    lines = [x for x in res.stderr.splitlines() if x.startswith("evolve: ")]
    assert [x.split(",")[0] for x in lines] == [
        "evolve: punctuations 0/2", "evolve: punctuations 1/2", "evolve: punctuations 2/2"]
    assert "~" in lines[1] and "elapsed" in lines[2]
    res = invoke("evolve", "--out", str(tmp_path / "b"), "--generations", "0", "--quiet", *SMALL)
    assert res.exit_code == 0 and res.stderr == ""
