"""The station's ``/fleet`` page: linked from its index, built from its records store."""

from __future__ import annotations

from pathlib import Path

from fleet_archive import OUTLIER, RIG_EFFECT, SIM_EFFECT, seed
from starlette.testclient import TestClient

from aatest.station import StationOptions, build

#: the station as a browser on this machine names it (its default port)
STATION_URL = "http://127.0.0.1:8671"


def test_fleet_page_names_the_rig_effect_and_the_outlier(tmp_path: Path) -> None:
    url = f"sqlite:///{tmp_path / 'records.sqlite'}"
    seed(url, tmp_path)
    client = TestClient(build(StationOptions(runs_dir=tmp_path / "runs", records=url)),
                        base_url=STATION_URL)
    assert 'href="/fleet"' in client.get("/").text
    page = client.get("/fleet", params={"model": "sr207"})
    assert page.status_code == 200
    assert "sandbox" in page.headers["content-security-policy"]  # a document: no script runs
    html = page.text
    rig = html[html.index('id="rig-TT-100"'):]
    row = rig[rig.index(f'data-effect="{RIG_EFFECT}"'):].split("</tr>")[0]
    assert ">rig effect<" in row
    assert f'<td class="t serial">{OUTLIER}</td>' in html
    assert SIM_EFFECT not in html


def test_without_a_records_store_there_is_no_fleet_page(tmp_path: Path) -> None:
    client = TestClient(build(StationOptions(runs_dir=tmp_path / "runs")), base_url=STATION_URL)
    answer = client.get("/fleet")
    assert answer.status_code == 404
    assert "--records" in answer.text


def test_the_fleet_page_needs_the_token_like_every_page(tmp_path: Path) -> None:
    url = f"sqlite:///{tmp_path / 'records.sqlite'}"
    seed(url, tmp_path)
    token = "t" * 40
    (tmp_path / "token").write_text(token)
    client = TestClient(build(StationOptions(runs_dir=tmp_path / "runs", records=url,
                                             token_file=tmp_path / "token")),
                        base_url=STATION_URL)
    assert client.get("/fleet").status_code == 401
    answer = client.get("/fleet", headers={"authorization": f"Bearer {token}"})
    assert answer.status_code == 200 and "Fleet diagnosis" in answer.text
