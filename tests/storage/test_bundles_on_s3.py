"""Run bundles on object storage, end to end through the CLI against a moto S3 server.

The same procedure and seed run once to ``s3://…`` and once to a local directory; everything
read back from the URL (analyze, verify, report, the records store) must agree with the local
run. Numbers are compared with the shared tolerances (tests/tolerances.py): the twin recorded
the same samples both times, so the results differ at most by floating-point rounding order.
"""

from __future__ import annotations

import json
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import pytest
from tolerances import leaves, mismatches
from typer.testing import CliRunner

from aatest.bundle import signing
from aatest.cli import app
from aatest.storage import RemotePath, locate

RUNNER = CliRunner()
PROCEDURE = Path(__file__).parents[2] / "src" / "aatest" / "procedures" / "scale-factor.yaml"
SEED = "4"


def aatest(*args: object) -> tuple[int, str, str]:
    result = RUNNER.invoke(app, [str(a) for a in args])
    return result.exit_code, result.stdout, result.stderr


@dataclass
class Archive:
    """One run on the S3 server and the same run (procedure, seed) on local disk."""

    bucket: str
    remote: RemotePath
    local: Path
    key: Path
    records: str
    staging: Path
    tmp: Path


@pytest.fixture(scope="module")
def archive(s3_endpoint: str, tmp_path_factory: pytest.TempPathFactory) -> Iterator[Archive]:
    tmp = tmp_path_factory.mktemp("s3-archive")
    records = f"sqlite:///{tmp / 'records.sqlite'}"
    with pytest.MonkeyPatch.context() as env:
        for name, value in (("AWS_ACCESS_KEY_ID", "testing"),
                            ("AWS_SECRET_ACCESS_KEY", "testing"),
                            ("AWS_DEFAULT_REGION", "us-east-1"),
                            ("AATEST_S3_ENDPOINT", s3_endpoint),
                            ("AATEST_STAGING", str(tmp / "staging")),
                            ("AATEST_RECORDS", records)):
            env.setenv(name, value)
        for name in ("AATEST_LAB", "AATEST_SIGNING_KEY", "AWS_ENDPOINT_URL", "AWS_PROFILE"):
            env.delenv(name, raising=False)
        from aatest.storage.location import filesystem

        filesystem("s3").mkdir("archive")
        key = tmp / "lab.key"
        assert aatest("keygen", key, "--no-passphrase")[0] == 0
        remote = locate("s3://archive/runs/r1")
        assert isinstance(remote, RemotePath)
        local = tmp / "local-r1"
        for out in (remote, local):
            code, stdout, stderr = aatest("run", PROCEDURE, "--out", out, "--seed", SEED,
                                          "--no-progress", "--sign-key", key)
            assert code == 0, stdout + stderr
        yield Archive("archive", remote, local, key, records, tmp / "staging", tmp)


def _copy(archive: Archive, name: str) -> RemotePath:
    """A copy of the remote run under another prefix (for tests that change it)."""
    target = archive.remote.with_name(name)
    archive.remote.fs.copy(archive.remote.path, target.path, recursive=True)
    return target


def _numbers(document: dict[str, object]) -> dict[str, object]:
    """The analysis and verdict leaves: what a re-analysis must reproduce (not the
    ``runtime_s`` an analysis measures of itself: wall-clock time, not a result)."""
    return {path: value for path, value in leaves(document)
            if path.startswith((".analysis.", ".verdicts", ".uncertainty"))
            and not path.endswith("runtime_s")}


def test_run_to_s3_uploads_the_bundle_the_local_run_writes(archive: Archive) -> None:
    local_names = sorted(p.relative_to(archive.local).as_posix()
                         for p in archive.local.rglob("*") if p.is_file() and p.name != "run.lock")
    assert archive.remote.members() == local_names
    assert "recording.mcap" in local_names and "report.html.sig" in local_names
    assert not any(archive.staging.iterdir()), "the staging copy goes once uploaded"


def test_analyze_from_s3_equals_the_local_run(archive: Archive) -> None:
    out = archive.tmp / "analysed-from-s3"
    code, stdout, stderr = aatest("analyze", archive.remote, "--out", out)
    assert code == 0, stdout + stderr
    got = _numbers(json.loads((out / "results.json").read_text()))
    want = _numbers(json.loads((archive.local / "results.json").read_text()))
    assert len(got) > 20 and got.keys() == want.keys()
    assert mismatches(got, want) == []


def test_analyze_writes_its_bundle_back_to_s3_signed(archive: Archive) -> None:
    target = archive.remote.with_name("reanalysed")
    code, stdout, stderr = aatest("analyze", archive.remote, "--out", target,
                                  "--sign-key", archive.key)
    assert code == 0, stdout + stderr
    assert target.members() == ["report.html", "report.html.sig", "results.json"]
    code, stdout, stderr = aatest("verify", target / "report.html", "--public-key",
                                  f"{archive.key}.pub")
    assert code == 0, stdout + stderr
    assert "signature valid" in stdout and "matches its record" in stdout


def test_verify_on_s3_passes_and_names_a_tampered_object(archive: Archive) -> None:
    code, stdout, stderr = aatest("verify", archive.remote / "report.html", "--public-key",
                                  f"{archive.key}.pub")
    assert code == 0, stdout + stderr
    tampered = _copy(archive, "tampered")
    results = tampered / "results.json"
    results.write_text(results.read_text().replace('"pass"', '"fail"', 1))
    recording = tampered / "recording.mcap"
    data = bytearray(recording.read_bytes())
    data[len(data) // 2] ^= 0x01
    recording.write_bytes(bytes(data))
    code, stdout, stderr = aatest("verify", tampered / "report.html", "--public-key",
                                  f"{archive.key}.pub")
    assert code == 1, stdout + stderr
    assert "results.json: modified" in stderr and "recording.mcap: modified" in stderr


def test_report_from_s3_re_signs_in_place(archive: Archive) -> None:
    copy = _copy(archive, "re-reported")
    before = (copy / "report.html.sig").read_text()
    code, stdout, stderr = aatest("report", copy, "--sign-key", archive.key)
    assert code == 0, stdout + stderr
    assert stdout.strip() == f"report: {copy / 'report.html'}"
    assert (copy / "report.html.sig").read_text() != before
    code, stdout, stderr = aatest("verify", copy / "report.html", "--public-key",
                                  f"{archive.key}.pub")
    assert code == 0, stdout + stderr


def test_records_store_registers_and_shows_the_s3_bundle(archive: Archive) -> None:
    code, stdout, stderr = aatest("records", "list", "--include-simulations")
    assert code == 0, stderr
    assert f"{archive.remote}/report.html" in stdout
    code, stdout, stderr = aatest("records", "show", "1")  # the first run registered
    assert code == 0, stderr
    record = json.loads(stdout)
    assert record["bundle"] == f"{archive.remote}/report.html"
    assert record["bundle_problems"] == []
    assert set(record["files"]) == set(archive.remote.members()) - {"report.html.sig"}


def test_diagnose_from_s3_says_what_it_says_of_the_local_run(archive: Archive) -> None:
    """The same recorded samples diagnosed from the URL and from disk: the same printed
    diagnosis (numbers rounded for print), and its report uploaded beside the recording."""
    copy = _copy(archive, "diagnosed")
    remote_code, remote_out, remote_err = aatest("diagnose", copy)
    local_code, local_out, local_err = aatest("diagnose", archive.local)
    assert remote_code in (0, 1) and remote_code == local_code, remote_err + local_err
    assert remote_out == local_out and "gain" in remote_out
    assert "diagnosis.html" in copy.members()
    # the signature still holds (diagnosis.* is outside what it covers); the records store is
    # left out here: an earlier test re-signed another copy under the same certificate number
    checked = signing.verify_bundle(copy / "report.html",
                                    [signing.trusted_public_key(Path(f"{archive.key}.pub"))])
    assert checked.ok, checked.reasons


def test_station_history_lists_the_s3_record_without_file_links(archive: Archive) -> None:
    from aatest.station.catalogue import history_for

    rows = history_for(archive.records, archive.tmp / "station-runs").recent(10)
    number = json.loads((archive.remote / "results.json").read_text())["certificate_number"]
    s3_rows = [r for r in rows if r["certificate_number"] == number]
    assert s3_rows and all(r["name"] is None and r["files"] == [] for r in s3_rows)


@pytest.mark.parametrize(("command", "url", "named"), [
    (("analyze",), "s3://no-such-bucket-q/r1", "bucket 'no-such-bucket-q' does not exist"),
    (("analyze",), "s3://archive/runs/absent", "no such object or prefix"),
    (("verify",), "s3://archive/runs/absent/report.html", "no such object or prefix"),
    (("report",), "s3://archive/runs/absent", "no such object or prefix"),
    (("diagnose",), "nosuch://x/r1", "unknown storage scheme"),
])
def test_a_bad_url_is_bad_input_naming_it(archive: Archive, command: tuple[str, ...], url: str,
                                          named: str) -> None:
    code, _, stderr = aatest(*command, url)
    assert code == 2 and f"{url}: " in stderr and named in stderr, stderr


def test_run_to_a_missing_bucket_is_refused_before_anything_moves(archive: Archive) -> None:
    code, _, stderr = aatest("run", PROCEDURE, "--out", "s3://no-such-bucket-q/r9",
                             "--no-progress")
    assert code == 2 and "s3://no-such-bucket-q/r9: bucket 'no-such-bucket-q'" in stderr
    assert not any(archive.staging.iterdir()), "nothing was recorded"
