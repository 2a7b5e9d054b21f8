"""find_manifest (issue 25: the demo no longer guesses where a log's manifest lies): the
given manifest, else the table's neighbour <stem>.yaml, then <stem>.yml, else none."""

from __future__ import annotations

from are_stats.logs import find_manifest


def test_the_neighbour_given_or_none(tmp_path):
    log = tmp_path / "log.csv"
    log.write_text("id,t_arrive,t_leave\na,1,2\n")
    meta, where = find_manifest(log)
    assert meta == {} and where == f"{tmp_path / 'log.yaml'} (not found)"
    (tmp_path / "log.yml").write_text("window: [0, 10]\ndescription: second choice\n")
    meta, where = find_manifest(log)
    assert where == str(tmp_path / "log.yml") and meta["window"] == [0.0, 10.0]
    (tmp_path / "log.yaml").write_text("window: [0, 20]\n")
    meta, where = find_manifest(str(log))  # <stem>.yaml before <stem>.yml
    assert where == str(tmp_path / "log.yaml") and meta == {"window": [0.0, 20.0]}
    other = tmp_path / "other.yaml"
    other.write_text("window: [5, 6]\ndescription: given\n")
    meta, where = find_manifest(log, other)
    assert where == str(other) and meta["description"] == "given"
