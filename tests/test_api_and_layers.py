"""The Python API as the README shows it, the packaged cases by name, the run layer's verdict,
and the import graph of the packages (lower layers never import upper ones; no circles)."""

import ast
import re
from pathlib import Path

import numpy as np
import pytest

import eulag

from .test_cli_coupled import CASE

ROOT = Path(__file__).resolve().parent.parent

#: the tiny periodic coupled case of the CLI tests, named, with a station and four passes
TINY_TOML = (CASE.replace('name = "killme"', 'name = "tiny_api"')
             .replace('mode = "periodic"', 'mode = "periodic"\nsections = [0.25]')
             .replace("max_passes = 8", "max_passes = 4"))


def _readme_python_block() -> str:
    text = (ROOT / "README.md").read_text()
    blocks = re.findall(r"```python\n(.*?)```", text, flags=re.S)
    assert blocks, "README.md has no python example"
    return blocks[0]


def test_readme_example_runs_on_a_tiny_case(tmp_path, monkeypatch):
    """The README's Python example, verbatim except for the case file (a tiny periodic pipe
    instead of the base case), the parcel count and the axial station."""
    code = _readme_python_block()
    case_files = re.findall(r'"(cases/[^"]+\.toml)"', code)
    assert case_files, "the README example should load a case file"
    tiny = tmp_path / "tiny_api.toml"
    tiny.write_text(TINY_TOML)
    for c in case_files:
        code = code.replace(f'"{c}"', f'"{tiny}"')
    code = re.sub(r"parcels=\d+", "parcels=1500", code)
    code = re.sub(r"x=\d+(\.\d*)?", "x=0.25", code)  # the tiny pipe is 0.5 m long
    monkeypatch.chdir(tmp_path)
    ns: dict = {}
    exec(compile(code, "README.md", "exec"), ns)  # noqa: S102 - the documented example itself
    assert (tmp_path / "out.nc").is_file()
    ds = eulag.open_dataset(tmp_path / "out.nc")
    assert "gas_ux" in ds and ds.attrs["case_name"] == "tiny_api"


def test_packaged_cases_load_by_name():
    from eulag import runs

    names = runs.packaged_cases()
    assert "tsuji_morikawa_200um" in names and "scene_h" in names
    case = runs.load_case("tsuji_morikawa_200um")
    assert case.name == "tsuji_morikawa_200um" and case.particles.diameter == pytest.approx(200e-6)
    assert eulag.Case.from_file("scene_a").name == "scene_a"
    with pytest.raises(runs.BadInput, match="no such case file or packaged case"):
        runs.load_case("no_such_case_name")


def test_a_directory_given_as_the_case_is_named_so(tmp_path, monkeypatch):
    from eulag import runs

    monkeypatch.chdir(tmp_path)
    (tmp_path / "adir").mkdir()
    for spec in ("adir", tmp_path / "adir"):
        with pytest.raises(runs.BadInput, match=r"adir: is a directory; allowed: a case file \(.toml\)"):
            runs.load_case(spec)
    (tmp_path / "scene_a").mkdir()  # a folder named like a packaged case does not hide it
    assert runs.load_case("scene_a").name == "scene_a"


def test_unknown_model_is_bad_input(tmp_path):
    from eulag import runs

    p = tmp_path / "m.toml"
    p.write_text('model = "lattice-boltzmann"\n' + TINY_TOML)
    with pytest.raises(runs.BadInput, match=r"model = 'lattice-boltzmann': unknown model; allowed: "
                                            r"euler-lagrange, dem-darcy, two-fluid") as err:
        runs.load_case(p)
    assert err.value.status == 2


def test_unconverged_run_reports_the_failing_criterion(tmp_path, capsys):
    """Two early passes cannot meet the residual criterion (it needs four): the run stops at
    max_passes, exit status 1, and says which criterion failed with value and threshold; the
    dataset holds the same verdict."""
    from eulag.cli import main

    p = tmp_path / "short.toml"
    p.write_text(TINY_TOML.replace("max_passes = 4", "max_passes = 4\ncoupling_tolerance = 1.5"))
    status = main(["run", str(p), "-o", str(tmp_path / "o.nc"), "--quiet", "--no-plots"])
    err = capsys.readouterr().err
    assert status == 1
    assert "not converged when max_passes = 4 was reached (as judged after pass 2, before the 2 final passes)" in err
    assert re.search(r"residual [0-9.]+ >= 1\.5 \(RMS change of the relaxed sources over their noise; "
                     r"judged from pass 4 on, this was pass 2\)", err), err
    ds = eulag.open_dataset(tmp_path / "o.nc")
    assert int(ds["converged"]) == 0 and "residual" in ds.attrs["stop_reason"]
    # every pass a final pass: no early pass was judged, and the verdict says so
    p.write_text(TINY_TOML.replace("max_passes = 4", "max_passes = 2"))
    assert main(["run", str(p), "-o", str(tmp_path / "o2.nc"), "--quiet", "--no-plots"]) == 1
    err = capsys.readouterr().err
    assert ("max_passes = 2 leaves no early pass to judge convergence after (all 2 passes were final passes"
            in err and "pass 0" not in err and "gas solve" not in err), err
    crit = [str(c) for c in ds["criterion_name"].values]
    assert crit[:2] == ["gas_solve", "residual"]
    i = crit.index("residual")
    assert int(ds["criterion_met"].values[i]) == 0 and float(ds["criterion_threshold"].values[i]) == 1.5
    assert ds["criterion_history"].dims == ("iteration", "criterion")


# ------------------------------------------------------------------ import graph
PACKAGES = ("eulag", "rans", "particles", "collisions", "dem", "darcy", "tfm", "jitcache")
#: what each package may import of the others (README.md, "Layout")
ALLOWED = {
    "jitcache": set(),
    "rans": {"jitcache"},
    "collisions": {"jitcache"},
    "darcy": set(),
    "particles": {"collisions", "rans", "jitcache"},
    "dem": {"collisions", "jitcache"},
    "tfm": {"rans"},
    "eulag": {"rans", "particles", "collisions", "dem", "darcy", "tfm", "jitcache"},
}


def _imports(path: Path, package: str) -> set[str]:
    """Fully qualified project modules imported by the file at ``path`` (module ``package...``)."""
    tree = ast.parse(path.read_text())
    mod = ".".join(path.relative_to(ROOT).with_suffix("").parts)
    if mod.endswith(".__init__"):
        mod = mod[: -len(".__init__")]
        pkg_parts = mod.split(".")
    else:
        pkg_parts = mod.split(".")[:-1]
    out = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = pkg_parts[: len(pkg_parts) - node.level + 1]
                name = ".".join(base + ([node.module] if node.module else []))
                if node.module is None:
                    out.update(f"{name}.{a.name}" for a in node.names)
                else:
                    out.add(name)
            elif node.module:
                out.add(node.module)
                out.update(f"{node.module}.{a.name}" for a in node.names)
    return {m for m in out if m.split(".")[0] in PACKAGES}


def _module_files():
    for pkg in PACKAGES:
        d = ROOT / pkg
        if d.is_dir():
            yield from ((pkg, f) for f in sorted(d.rglob("*.py")))


def test_lower_layers_never_import_upper_ones():
    bad = []
    for pkg, f in _module_files():
        for m in _imports(f, pkg):
            top = m.split(".")[0]
            if top != pkg and top not in ALLOWED[pkg]:
                bad.append(f"{f.relative_to(ROOT)} imports {m}")
    assert not bad, bad


def test_no_import_circle_among_modules():
    """Module-level graph (every import, lazy ones included), each edge to an existing module
    file; a cycle is a strongly connected component of more than one module."""
    files = {}
    for pkg, f in _module_files():
        mod = ".".join(f.relative_to(ROOT).with_suffix("").parts)
        files[mod[: -len(".__init__")] if mod.endswith(".__init__") else mod] = f
    graph = {}
    for mod, f in files.items():
        deps = set()
        for m in _imports(f, mod.split(".")[0]):
            while m and m not in files:
                m = m.rpartition(".")[0]
            # a package's __init__ re-exporting its own modules is not a circle of the design
            if m and m != mod and not mod.startswith(m + ".") and not m.startswith(mod + "."):
                deps.add(m)
        graph[mod] = deps
    index, low, stack, on, cycles = {}, {}, [], set(), []
    counter = [0]

    def strong(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in graph[v]:
            if w not in index:
                strong(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                cycles.append(sorted(comp))

    import sys

    sys.setrecursionlimit(10000)
    for v in graph:
        if v not in index:
            strong(v)
    assert not cycles, cycles


def test_case_reference_is_current():
    """docs/case-reference.md is what the schema generates (python -m eulag.config
    docs/case-reference.md), and names every key of every section."""
    from eulag.config import _SECTIONS, _public_fields, key_reference

    text = (ROOT / "docs" / "case-reference.md").read_text(encoding="utf-8")
    assert text == key_reference(), "regenerate: python -m eulag.config docs/case-reference.md"
    for name, cls in _SECTIONS.items():
        for f in _public_fields(cls):
            assert f"| `{f.name}` |" in text, f"{name}.{f.name}"


def test_python_api_rejects_wrong_arguments_before_any_work(tmp_path):
    import xarray as xr

    import eulag
    from eulag import analysis
    from eulag.config import CaseError
    from eulag.runs import BadInput

    case = eulag.Case.from_file("tsuji_morikawa_200um")
    for kwargs, what in (({"out": tmp_path}, "is a directory"), ({"out": tmp_path / "x.txt"}, "ending in .nc"),
                         ({"out": tmp_path / "no" / "x.nc"}, "does not exist"), ({"out": 5}, "wrong type"),
                         ({"parcels": 1.5}, "wrong type"), ({"parcels": True}, "wrong type"),
                         ({"parcels": 0}, "out of range"), ({"resume": "no"}, "allowed: True or False"),
                         ({"resume": 1}, "allowed: True or False")):
        with pytest.raises(BadInput, match=what):
            eulag.run(case, **kwargs)
    with pytest.raises(BadInput, match="wrong type; allowed: an eulag.Case"):
        eulag.run({"name": "x"})
    tf = ROOT / "cases" / "two_fluid" / "ding_qs0.4.toml"
    with pytest.raises(BadInput, match="tracks no parcels"):
        eulag.run(tf, out=tmp_path / "tf.nc", parcels=10)
    with pytest.raises(CaseError, match="wrong type"):
        eulag.Case.from_file(123)
    with pytest.raises(CaseError, match="not a case of the Euler-Lagrange model"):
        eulag.Case.from_file(tf)
    assert list(tmp_path.iterdir()) == []  # nothing computed, nothing written
    (tmp_path / "notes.nc").write_text("not a dataset\n")
    for path, err, what in ((tmp_path, ValueError, "is a directory"), (tmp_path / "absent.nc", FileNotFoundError,
                                                                     "no such result file"),
                            (tmp_path / "notes.nc", ValueError, "cannot be read as a NetCDF dataset")):
        with pytest.raises(err, match=what) as info:
            eulag.open_dataset(path)
        assert "\n" not in str(info.value) and "http" not in str(info.value)
    slug = xr.Dataset(attrs={"model": "dem-darcy"})
    for fn in (analysis.pressure_drop_summary, analysis.secondary_flow_strength, analysis.recirculation_cells):
        with pytest.raises(ValueError, match="model = 'dem-darcy' dataset; allowed: an Euler-Lagrange dataset"):
            fn(slug)
        with pytest.raises(ValueError, match="allowed: an xarray.Dataset"):
            fn({"gas_uy": 1})
    with pytest.raises(ValueError, match="not a number"):
        analysis.check_station(slug, "abc")
