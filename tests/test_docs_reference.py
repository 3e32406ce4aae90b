"""The API reference covers every public name: ``docs/gen_ref.py`` expands the reference
pages from ``__all__`` (no MkDocs needed to check it)."""

import importlib.util
import re
import types
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("jaxtube", "fitting", "fitting.continuum")


def _gen_ref():
    spec = importlib.util.spec_from_file_location("gen_ref", ROOT / "docs" / "gen_ref.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.mark.parametrize("package", PACKAGES)
def test_reference_lists_every_public_name_once(package):
    gen_ref = _gen_ref()
    markdown = gen_ref.reference_markdown(package)
    documented = re.findall(rf"^::: {re.escape(package)}\.(\w+)$", markdown, re.M)
    names = importlib.import_module(package).__all__
    assert sorted(documented) == sorted(names)


@pytest.mark.parametrize("package", PACKAGES)
def test_all_holds_every_public_name(package):
    """A name re-exported by a package but left out of its ``__all__`` would be public and
    undocumented."""
    module = importlib.import_module(package)
    public = {name for name, value in vars(module).items()
              if not name.startswith("_") and not isinstance(value, types.ModuleType)
              and name not in ("annotations",)}
    assert sorted(public - set(module.__all__)) == []


def test_every_package_has_a_reference_page():
    pages = " ".join(p.read_text() for p in (ROOT / "docs" / "reference").glob("*.md"))
    for package in PACKAGES:
        assert f"<!-- reference: {package} -->" in pages


def test_readme_is_short_and_its_links_resolve():
    """The front page stays a front page (issue 35: at most 200 lines), and every relative
    link or image of it names a file of the repository (MkDocs checks the site's own)."""
    text = (ROOT / "README.md").read_text()
    assert len(text.splitlines()) <= 200
    targets = re.findall(r"\]\(([^)#\s]+)(?:#[^)]*)?\)", text)
    relative = [t for t in targets if "://" not in t]
    assert relative, "no relative links found: the pattern no longer matches the README"
    missing = [t for t in relative if not (ROOT / t).exists()]
    assert not missing, f"README.md links to missing files: {missing}"
