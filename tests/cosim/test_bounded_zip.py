"""Archives from elsewhere are unpacked within bounds: the campaign's zip bomb (3.1 MB -> 3.2 GB)
as an SSP package, as an FMU file and as an FMU nested in a package; generated archives (names
that climb out, absolute, Windows and NUL names, duplicates, links, oversized and high-ratio
members, too many members, forged sizes) against small bounds. Every case: one line naming the
archive and the member, nothing left beside the target, the cache untouched."""
from __future__ import annotations

import os
import stat
import zipfile
from pathlib import Path, PurePosixPath

import pytest
from conftest import OSCILLATOR, make_scene  # at collection: the conftest of this folder
from featherstar.cosim.errors import SceneError
from featherstar.cosim.fmi.bounded_zip import ZipLimits, extract_bounded
from featherstar.cosim.scene.data import scene_from_dict
from featherstar.cosim.scene.graph import plan
from featherstar.cosim.scenes import load_scene
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st
from zip_bombs import bomb

pytestmark = pytest.mark.filterwarnings("ignore:Duplicate name:UserWarning")
LIMITS = ZipLimits(max_members=8, max_member_bytes=64 << 10, max_total_bytes=128 << 10, max_ratio=20.0,
                   ratio_floor_bytes=4 << 10)
SSD = b"""<?xml version="1.0"?><ssd:SystemStructureDescription version="1.0" name="b"
 xmlns:ssd="http://ssp-standard.org/SSP1/SystemStructureDescription"><ssd:System name="r"/>
</ssd:SystemStructureDescription>"""


@pytest.fixture
def cache(tmp_path, monkeypatch):
    monkeypatch.setenv("FEATHERSTAR_CACHE", str(tmp_path / "cache"))
    return tmp_path / "cache"


def _leftovers(folder: Path) -> list[str]:
    return sorted(str(p.relative_to(folder)) for p in folder.rglob("*")) if folder.exists() else []


def test_the_campaigns_zip_bomb_package_is_refused_before_it_fills_the_disk(tmp_path, cache):
    package = bomb(tmp_path / "bomb.ssp", extra={"SystemStructure.ssd": SSD})
    assert package.stat().st_size < 4 << 20
    assert sum(i.file_size for i in zipfile.ZipFile(package).infolist()) > 3 << 30
    with pytest.raises(SceneError) as refused:
        load_scene(package)
    line = str(refused.value)
    assert "\n" not in line and f"SSP package '{package}'" in line and "resources/bomb000.bin" in line, line
    assert "zip bomb" in line
    assert _leftovers(cache / "ssp") == []


def test_a_bomb_under_the_ratio_is_still_refused_by_the_total(tmp_path, cache):
    """Random-looking data compresses not at all: only the total bounds it."""
    limits = ZipLimits(max_total_bytes=3 << 20)
    noise = os.urandom(1 << 20)
    archive = tmp_path / "big.zip"
    with zipfile.ZipFile(archive, "w") as z:
        for i in range(4):
            z.writestr(f"part{i}.bin", noise)
    with pytest.raises(SceneError, match=r"unpacks to more than 3.0 MB .* member 'part3.bin'"):
        extract_bounded(archive, tmp_path / "out", "archive", limits)
    assert _leftovers(tmp_path) == ["big.zip"]


def _fmu_scene(fmu: Path):
    return scene_from_dict({"name": "b", "connections": [], "master": {"t_end_s": 0.1},
                            "blocks": {"x": {"kind": "fmu", "fmu": str(fmu)}}})


def test_an_fmu_bomb_is_refused_before_its_model_description_is_read(tmp_path):
    fmu = bomb(tmp_path / "bomb.fmu", members=8, prefix="resources/table",
               extra={"modelDescription.xml": b"<fmiModelDescription/>"})
    with pytest.raises(SceneError) as refused:
        plan(_fmu_scene(fmu))
    assert "block 'x'" in str(refused.value) and "resources/table000.bin" in str(refused.value)
    assert "zip bomb" in str(refused.value)


def test_an_fmu_bomb_nested_in_a_package_is_refused_when_the_package_is_used(tmp_path, cache):
    inner = bomb(tmp_path / "inner.fmu", members=8, prefix="resources/table",
                 extra={"modelDescription.xml": b"<fmiModelDescription/>"})
    ssd = SSD.replace(b'<ssd:System name="r"/>', b'<ssd:System name="r"><ssd:Elements><ssd:Component name="x" '
                      b'source="resources/x.fmu"/></ssd:Elements></ssd:System>')
    package = tmp_path / "nested.ssp"
    with zipfile.ZipFile(package, "w") as z:
        z.writestr("SystemStructure.ssd", ssd)
        z.write(inner, "resources/x.fmu")
    scene = load_scene(package)   # the package itself is small and well formed
    with pytest.raises(SceneError, match=r"block 'x'.*resources/table000.bin.*zip bomb"):
        plan(scene)


# --- generated archives ------------------------------------------------------------------------

SAFE = st.from_regex(r"[a-z]{1,6}(/[a-z]{1,6}){0,2}\.[a-z]{1,3}", fullmatch=True)
UNSAFE = st.sampled_from(["../evil", "a/../../evil", "/etc/evil", "..", "a\\..\\evil", "C:evil", "a\x00b",
                          "resources/../../x.fmu"])


@st.composite
def members(draw):
    name = draw(UNSAFE if draw(st.integers(0, 11)) == 0 else SAFE)
    kind = draw(st.sampled_from(["zeros", "noise", "text"]))
    size = draw(st.integers(0, 96 << 10))
    content = {"zeros": bytes(size), "noise": os.urandom(size),
               "text": (b"<x>featherstar</x>\n" * (size // 19 + 1))[:size]}[kind]
    return name, content, draw(st.booleans())


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(entries=st.integers(1, 9).flatmap(lambda n: st.lists(members(), min_size=n, max_size=n)),
       link=st.sampled_from([False] * 7 + [True]))
def test_generated_archives_unpack_within_bounds_or_are_refused_leaving_nothing(tmp_path, entries, link):
    work = tmp_path / f"case-{os.getpid()}-{len(list(tmp_path.iterdir()))}"
    work.mkdir()
    archive = work / "a.zip"
    with zipfile.ZipFile(archive, "w") as z:
        for index, (name, content, deflate) in enumerate(entries):
            info = zipfile.ZipInfo(name)
            info.compress_type = zipfile.ZIP_DEFLATED if deflate else zipfile.ZIP_STORED
            if link and index == 0:
                info.external_attr = (stat.S_IFLNK | 0o777) << 16
            z.writestr(info, content)
    infos = zipfile.ZipFile(archive).infolist()
    target = work / "out"
    try:
        extract_bounded(archive, target, "archive 'a.zip'", LIMITS)
    except SceneError as exc:
        line = str(exc)
        assert "\n" not in line and line.startswith("archive 'a.zip': "), line
        assert "archive member '" in line or "members" in line or "more than" in line, line
        assert _leftovers(work) == ["a.zip"], _leftovers(work)
        event(f"refused: {line.split(chr(39))[-1].strip()[:40]}")
        return
    # Unpacked: then every bound held and every file is inside the target, byte for byte.
    names = [i.filename for i in infos]
    assert len(names) <= LIMITS.max_members and len(set(names)) == len(names)
    assert sum(i.file_size for i in infos) <= LIMITS.max_total_bytes
    assert not (link and infos)
    for info in infos:
        path = PurePosixPath(info.filename)
        assert not path.is_absolute() and ".." not in path.parts and "\\" not in info.filename
        assert info.file_size <= LIMITS.max_member_bytes
        assert info.file_size < LIMITS.ratio_floor_bytes or info.file_size <= LIMITS.max_ratio * info.compress_size
        out = target / path
        assert out.resolve().is_relative_to(target.resolve())
        if not info.is_dir():
            assert out.read_bytes() == zipfile.ZipFile(archive).read(info)
    assert sorted(p.name for p in work.iterdir()) == ["a.zip", "out"]
    event("unpacked")


def test_a_forged_size_is_refused_and_leaves_nothing(tmp_path):
    """The central directory says 1 kB, the data holds 32 kB: never more than declared is written."""
    archive = tmp_path / "forged.zip"
    with zipfile.ZipFile(archive, "w", zipfile.ZIP_DEFLATED) as z:
        z.writestr("data.bin", bytes(32 << 10))
    raw = bytearray(archive.read_bytes())
    central = raw.rindex(b"PK\x01\x02")
    raw[central + 24:central + 28] = (1024).to_bytes(4, "little")   # uncompressed size in the directory
    local = raw.index(b"PK\x03\x04")
    raw[local + 22:local + 26] = (1024).to_bytes(4, "little")
    archive.write_bytes(bytes(raw))
    with pytest.raises(SceneError, match="archive 'forged.zip': .*data.bin|archive 'forged.zip': cannot unpack"):
        extract_bounded(archive, tmp_path / "out", "archive 'forged.zip'", LIMITS)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["forged.zip"]


def test_the_cache_quota_refuses_a_package_that_does_not_fit(tmp_path, cache, monkeypatch):
    package = tmp_path / "fits.ssp"
    with zipfile.ZipFile(package, "w") as z:
        z.writestr("SystemStructure.ssd", SSD)
        z.writestr("resources/table.bin", os.urandom(2 << 20))
    monkeypatch.setenv("FEATHERSTAR_SSP_CACHE_MB", "1")
    with pytest.raises(SceneError, match=r"cache .* holds 0 kB of its 1.0 MB quota"):
        load_scene(package)
    assert _leftovers(cache / "ssp") == []


# --- generated packages ------------------------------------------------------------------------

@pytest.fixture(scope="module")
def exported(tmp_path_factory) -> Path:
    from featherstar.cosim.ssp.export import export_ssp

    return export_ssp(make_scene(OSCILLATOR), tmp_path_factory.mktemp("ssp") / "osc.ssp")


ADDITIONS = {
    "traversal": (st.sampled_from(["../../evil.so", "/tmp/evil.so", "resources/../../evil", "..\\evil"]),
                  b"x", True),
    "high ratio": (st.just("resources/table.bin"), bytes(2 << 20), True),
    "link": (st.just("resources/link.fmu"), b"/etc/passwd", True),
    "duplicate": (st.just("SystemStructure.ssd"), b"<x/>", True),
    "harmless": (SAFE.map(lambda name: f"documentation/{name}"), b"notes", False),
}


@settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.data())
def test_a_mutated_package_is_refused_in_one_line_leaving_nothing(exported, tmp_path, monkeypatch, data):
    cache = tmp_path / f"cache-{len(list(tmp_path.iterdir()))}"
    monkeypatch.setenv("FEATHERSTAR_CACHE", str(cache))
    kinds = data.draw(st.lists(st.sampled_from(sorted(ADDITIONS)), min_size=1, max_size=3, unique=True))
    package = cache.parent / f"{cache.name}.ssp"
    refused_by = []
    with zipfile.ZipFile(exported) as original, zipfile.ZipFile(package, "w", zipfile.ZIP_DEFLATED) as z:
        for member in original.namelist():
            z.writestr(member, original.read(member))
        for kind in kinds:
            names, content, refused = ADDITIONS[kind]
            info = zipfile.ZipInfo(data.draw(names))
            info.compress_type = zipfile.ZIP_DEFLATED
            if kind == "link":
                info.external_attr = (stat.S_IFLNK | 0o777) << 16
            z.writestr(info, content)
            if refused:
                refused_by.append(info.filename)
    if not refused_by:
        load_scene(package)
        return
    with pytest.raises(SceneError) as refusal:
        load_scene(package)
    line = str(refusal.value)
    assert "\n" not in line and f"SSP package '{package}'" in line, line
    assert any(f"'{name}'" in line for name in refused_by), line
    assert _leftovers(cache / "ssp") == []
