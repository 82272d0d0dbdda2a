"""Plugin discovery and loading through real entry points.

Each test that needs installed plugins writes a real distribution (``*.dist-info`` with
``entry_points.txt`` plus its modules) into a temporary directory on ``sys.path``, so
``importlib.metadata`` finds it exactly as it finds a pip-installed package.
"""

from __future__ import annotations

import argparse
import importlib
import json
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

from edge_vis import plugins
from edge_vis.cli import plugins as plugins_command
from edge_vis.errors import PluginConflictError, PluginLoadError, PluginNotFoundError
from edge_vis.routing.bulk import BulkChannel
from edge_vis.routing.link import Link


class Base:
    """Stands for a plugin contract (such as the Link ABC) in the type checks."""


class Good(Base):
    pass


class Other:
    pass


class GoodLink(Link):
    """A link class, as the links group's contract wants."""


@pytest.fixture(autouse=True)
def _clean_state() -> Iterator[None]:
    modules = set(sys.modules)
    registry = {g: dict(v) for g, v in plugins._registry.items()}
    yield
    for name in set(sys.modules) - modules:
        if name.startswith("fakeplug"):
            del sys.modules[name]
    plugins._registry.clear()
    plugins._registry.update(registry)


def make_distribution(
    site: Path, dist: str, entry_points: dict[str, dict[str, str]], modules: dict[str, str]
) -> None:
    """Write an installed distribution: metadata, entry points and module sources."""
    info = site / f"{dist.replace('-', '_')}-1.0.dist-info"  # escaped as pip does
    info.mkdir(parents=True)
    (info / "METADATA").write_text(f"Metadata-Version: 2.1\nName: {dist}\nVersion: 1.0\n")
    lines = []
    for group, eps in entry_points.items():
        lines.append(f"[{group}]")
        lines += [f"{name} = {target}" for name, target in eps.items()]
    (info / "entry_points.txt").write_text("\n".join(lines) + "\n")
    for module, source in modules.items():
        (site / f"{module}.py").write_text(source)
    # Directory listings are cached by mtime, which may not tick between two writes.
    importlib.invalidate_caches()


@pytest.fixture
def site(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    site = tmp_path / "site"
    site.mkdir()
    monkeypatch.syspath_prepend(str(site))
    return site


@pytest.fixture
def fake_links(site: Path) -> Path:
    make_distribution(
        site,
        "fakeplug-links",
        {
            plugins.LINKS: {
                "fakeudp": "fakeplug_links:FakeUdp",
                "fakebroken": "fakeplug_broken:Thing",
                "fakens": "fakeplug_links:Namespace",
            },
            plugins.TRANSLATORS: {"fakeugv": "fakeplug_links:translator"},
        },
        {
            "fakeplug_links": (
                "from edge_vis.routing.link import Link\n"
                "IMPORTED = True\n"
                "class FakeUdp(Link):\n    scheme = 'fakeudp'\n"
                "class Namespace:\n    scheme = 'fakens'\n"
                "translator = object()\n"
            ),
            "fakeplug_broken": "import fakeplug_no_such_dependency\nThing = 1\n",
        },
    )
    return site


def test_listing_reports_every_group_without_importing(fake_links: Path) -> None:
    links = plugins.available(plugins.LINKS)
    assert links["fakeudp"] == ("fakeplug_links:FakeUdp", "fakeplug-links")
    assert links["fakebroken"] == ("fakeplug_broken:Thing", "fakeplug-links")
    assert plugins.available(plugins.TRANSLATORS)["fakeugv"][1] == "fakeplug-links"
    assert "fakeudp" not in plugins.available(plugins.MESSAGES)
    # Listing must not import: a broken plugin would otherwise break the listing.
    assert "fakeplug_links" not in sys.modules
    assert "fakeplug_broken" not in sys.modules


def test_load_imports_lazily_and_returns_the_target(fake_links: Path) -> None:
    cls = plugins.load(plugins.LINKS, "fakeudp")
    assert cls.scheme == "fakeudp"
    assert sys.modules["fakeplug_links"].IMPORTED is True


def test_missing_name_lists_what_exists_without_a_reinstall_hint(fake_links: Path) -> None:
    with pytest.raises(PluginNotFoundError) as info:
        plugins.load(plugins.LINKS, "carrier-pigeon")
    message = str(info.value)
    assert "link scheme 'carrier-pigeon'" in message
    assert "edge_vis.links" in message
    assert "fakeudp" in message and "fakebroken" in message
    # the scheme simply does not exist: reinstalling edge-vis would not help
    assert "pip install" not in message and "did you mean" not in message


@pytest.mark.parametrize(("typo", "meant"), [
    ("udpp", "'udp'"), ("upd", "'udp'"), ("seral", "'serial'"), ("Serail", "'serial'"),
    ("udq", "'udp'"),
])
def test_a_mistyped_link_scheme_names_the_likely_one(typo: str, meant: str) -> None:
    with pytest.raises(PluginNotFoundError) as info:
        plugins.load(plugins.LINKS, typo)
    message = str(info.value)
    assert f"did you mean {meant}?" in message
    assert "installed: " in message and "serial" in message and "pip install" not in message


def test_a_different_scheme_is_not_taken_for_a_typo() -> None:
    with pytest.raises(PluginNotFoundError) as info:
        plugins.load(plugins.LINKS, "tcp")
    assert "did you mean" not in str(info.value)


def test_missing_name_in_empty_group_says_none(monkeypatch: pytest.MonkeyPatch) -> None:
    with pytest.raises(PluginNotFoundError, match=r"installed: none\); is edge-vis installed"):
        plugins.load("edge_vis.nothing_here", "x")


def test_import_failure_names_the_plugin_and_keeps_the_cause(fake_links: Path) -> None:
    with pytest.raises(PluginLoadError) as info:
        plugins.load(plugins.LINKS, "fakebroken")
    err = info.value
    assert "'fakebroken'" in str(err) and "edge_vis.links" in str(err)
    assert "fakeplug_no_such_dependency" in str(err)
    assert isinstance(err.__cause__, ModuleNotFoundError)
    assert err.plugin == "fakebroken" and err.group == plugins.LINKS
    assert err.cause is err.__cause__


def test_register_then_load_round_trip() -> None:
    plugins.register(plugins.TRANSLATORS, "inline", Good)
    assert plugins.load(plugins.TRANSLATORS, "inline", expected_type=Base) is Good
    assert plugins.available(plugins.TRANSLATORS)["inline"] == (
        f"{__name__}:Good", plugins.REGISTERED,
    )
    plugins.unregister(plugins.TRANSLATORS, "inline")
    with pytest.raises(PluginNotFoundError):
        plugins.load(plugins.TRANSLATORS, "inline")


def test_registered_string_target_is_imported_like_an_entry_point(fake_links: Path) -> None:
    plugins.register(plugins.LINKS, "late", "fakeplug_links:FakeUdp")
    assert "fakeplug_links" not in sys.modules
    assert plugins.load(plugins.LINKS, "late").scheme == "fakeudp"
    plugins.register(plugins.LINKS, "late-broken", "fakeplug_broken:Thing")
    with pytest.raises(PluginLoadError, match="'late-broken'"):
        plugins.load(plugins.LINKS, "late-broken")


def test_registered_plugin_overrides_an_installed_one(fake_links: Path) -> None:
    plugins.register(plugins.LINKS, "fakeudp", GoodLink)
    assert plugins.load(plugins.LINKS, "fakeudp") is GoodLink


def test_expected_type_rejects_the_wrong_class_and_instance() -> None:
    plugins.register(plugins.LINKS, "wrong-class", Other)
    with pytest.raises(PluginLoadError, match=r"'wrong-class'.*class Other, not a Base"):
        plugins.load(plugins.LINKS, "wrong-class", expected_type=Base)
    plugins.register(plugins.MESSAGES, "instance", Good())
    assert isinstance(plugins.load(plugins.MESSAGES, "instance", expected_type=Base), Good)
    plugins.register(plugins.MESSAGES, "bad-instance", Other())
    with pytest.raises(PluginLoadError, match="'bad-instance'"):
        plugins.load(plugins.MESSAGES, "bad-instance", expected_type=Base)


def test_two_distributions_claiming_one_name_conflict(fake_links: Path) -> None:
    make_distribution(
        fake_links, "fakeplug-rival", {plugins.LINKS: {"fakeudp": "fakeplug_rival:Rival"}},
        {"fakeplug_rival": "class Rival:\n    pass\n"},
    )
    with pytest.raises(PluginConflictError) as info:
        plugins.load(plugins.LINKS, "fakeudp")
    assert "fakeplug-links" in str(info.value) and "fakeplug-rival" in str(info.value)


def run_command(*argv: str) -> int:
    parser = argparse.ArgumentParser()
    plugins_command.add_arguments(parser)
    return plugins_command.run(parser.parse_args(argv))


def test_cli_lists_plugins_as_json(fake_links: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert run_command("--json") == 0
    report = json.loads(capsys.readouterr().out)
    assert set(report) == set(plugins.GROUPS)
    row = next(r for r in report[plugins.LINKS] if r["name"] == "fakeudp")
    assert row == {
        "name": "fakeudp", "target": "fakeplug_links:FakeUdp",
        "distribution": "fakeplug-links", "version": "1.0",
    }


def test_cli_check_reports_the_broken_plugin(
    fake_links: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert run_command("--check", "--group", plugins.LINKS) == 1
    out = capsys.readouterr().out
    assert "edge_vis.translators" not in out
    fakeudp = next(line for line in out.splitlines() if "fakeudp" in line)
    broken = next(line for line in out.splitlines() if "fakebroken" in line)
    namespace = next(line for line in out.splitlines() if "fakens" in line)
    assert fakeudp.rstrip().endswith("ok")
    assert "FAILED" in broken and "fakeplug_no_such_dependency" in broken
    # a class that is not a Link (a namespace, as the bulk channel once was) is caught
    assert "FAILED" in namespace and "class Namespace, not a Link" in namespace


@pytest.mark.parametrize(
    ("group", "wrong"),
    [
        (plugins.LINKS, "links.udt:UdtBulkChannel"),       # a bulk channel is not a link
        (plugins.BULK, "links.udp:UdpLink"),               # nor a link a bulk channel
        (plugins.TRANSLATORS, "links.udp:UdpLink"),
        (plugins.MESSAGES, "translators.core:CoreTranslator"),
    ],
)
def test_every_group_checks_its_contract(group: str, wrong: str) -> None:
    plugins.register(group, "misplaced", wrong)
    with pytest.raises(PluginLoadError, match=r"'misplaced'.*, not a "):
        plugins.load(group, "misplaced")


def test_a_bulk_channel_must_provide_what_the_relay_uses() -> None:
    with pytest.raises(TypeError, match=r"lacks send_image, .*ImageService"):
        type("HalfChannel", (BulkChannel,), {"scheme": "half"})


def test_a_bulk_scheme_given_as_a_link_says_where_it_belongs() -> None:
    from edge_vis.routing.link import create_link

    with pytest.raises(PluginNotFoundError, match=r"udt:// is a bulk channel .*\[bulk\]"):
        create_link("udt://127.0.0.1:9000")


def test_installed_edge_vis_plugins_all_load() -> None:
    """Every plugin edge-vis itself declares must import (a typo in pyproject fails here)."""
    for group in plugins.GROUPS:
        for entry in plugins.entries(group):
            if entry.distribution == "edge-vis":
                plugins.load(group, entry.name)


def test_distribution_name_and_version_come_from_the_metadata_headers(site: Path) -> None:
    """Only the header block is read: a long description after it (pip puts the whole
    README there) with header-like lines in it changes nothing."""
    make_distribution(site, "fakeplug-doc", {plugins.LINKS: {"docudp": "fakeplug_doc:X"}},
                      {"fakeplug_doc": "X = 1\n"})
    meta = site / "fakeplug_doc-1.0.dist-info" / "METADATA"
    meta.write_text(meta.read_text() + "Description-Content-Type: text/markdown\n\n"
                    "# fakeplug-doc\n\nName: not-this\nVersion: 9.9\n" + "text\n" * 5000)
    [entry] = [e for e in plugins.entries(plugins.LINKS) if e.name == "docudp"]
    assert (entry.distribution, entry.version) == ("fakeplug-doc", "1.0")


def test_a_miss_is_told_from_the_look_up_that_missed(monkeypatch: pytest.MonkeyPatch) -> None:
    """A reinstall rewriting the metadata mid-look-up (seen when a second venv installed the
    same tree) once gave "no translator 'emergency' (installed: ..., emergency, ...); did you
    mean 'emergency'?": the list was read again after the miss. Here the metadata read is
    replaced (a stand-in for the rewrite) so that only its first read comes back empty."""
    real = plugins.metadata.entry_points
    reads: list[int] = []

    def rewriting(**kwargs: object) -> object:
        reads.append(1)
        return real(group="no.such.group") if len(reads) == 1 else real(**kwargs)

    monkeypatch.setattr(plugins.metadata, "entry_points", rewriting)
    with pytest.raises(PluginNotFoundError) as info:
        plugins.load(plugins.LINKS, "udp")
    message = str(info.value)
    assert "installed: none" in message and "did you mean" not in message
    assert len(reads) == 1
