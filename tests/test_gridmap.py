import pytest

from missionplan.maps.gridmap import GridMap, MapError, format_map, load_map, parse_map, save_map

TEXT = """# a hand-written map
name: tiny
title: two blocks
cell_m: 1.5
launch: 1,1  3,6
grid:
########
#......#
#.##o#.#
#......#
########
"""


def test_parse_and_round_trip(tmp_path):
    gmap = parse_map(TEXT, "tiny.map")
    assert gmap.name == "tiny" and gmap.shape == (5, 8)
    assert gmap.launch == [(1, 1), (3, 6)]
    assert gmap.meta == {"title": "two blocks", "cell_m": "1.5"}
    assert gmap.target.sum() == 6 + 2 + 6 and not gmap.target[2, 4] and gmap.free[2, 4]
    save_map(gmap, tmp_path / "tiny.map", comment="round trip")
    again = load_map(tmp_path / "tiny.map")
    assert format_map(again) == format_map(gmap)
    assert GridMap.from_rows("x", gmap.rows_text()).rows_text() == gmap.rows_text()


@pytest.mark.parametrize("bad, message", [
    (TEXT.replace("grid:\n", ""), "no 'grid:' section"),
    (TEXT.replace("#......#\n#.##", "#......##\n#.##", 1), "row 1 has 9 cells"),
    (TEXT.replace("#.##o#.#", "#.##x#.#"), "unknown cell character 'x'"),
    (TEXT.replace("launch: 1,1", "launch: 2,2"), "launch cell 1 (2, 2) is inside an obstacle"),
    (TEXT.replace("launch: 1,1", "launch: 9,1"), "outside"),
    (TEXT.replace("launch: 1,1", "launch: 1;1"), "is not 'row,col'"),
    (TEXT.replace("title: two blocks", "title two blocks"), "expected 'key: value'"),
])
def test_errors_name_the_file_and_problem(bad, message):
    with pytest.raises(MapError, match="tiny.map") as err:
        parse_map(bad, "tiny.map")
    assert message in str(err.value)


def test_missing_file(tmp_path):
    with pytest.raises(MapError, match="cannot read map file"):
        load_map(tmp_path / "none.map")


def test_saved_files_get_normal_permissions_and_no_temp_left(tmp_path):
    import os
    import stat

    gmap = parse_map(TEXT, "tiny.map")
    save_map(gmap, tmp_path / "tiny.map")
    mask = os.umask(0)
    os.umask(mask)
    assert stat.S_IMODE((tmp_path / "tiny.map").stat().st_mode) == 0o666 & ~mask
    assert [p.name for p in tmp_path.iterdir()] == ["tiny.map"]
