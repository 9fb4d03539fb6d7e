"""Every magnitude of the simulator has a published source, or is an estimate declared with its
range in `fabricjax/sim/estimates.py` (see the tags in `fabricjax/sim/calibration.py`'s docstring),
and the registry is what the simulator runs on: overriding an estimate changes the data, going
back restores it byte for byte."""

from __future__ import annotations

import ast
import io
import re
import tokenize
from pathlib import Path

import numpy as np
import pytest

from fabricjax.sim import calibration as cal
from fabricjax.sim import estimates, trial
from fabricjax.sim.scene import Scene

REPO = Path(__file__).parents[1]
SIM = REPO / "fabricjax" / "sim"
SOURCE_TAG = re.compile(r"\[(paper|ds|minsight|insight|FACTS|cited|law|numerics)\b")
CONSTANT = re.compile(r"^[A-Z][A-Z0-9_]*$")
REFERENCE = re.compile(r"^_?[A-Z][A-Z0-9_]*$")  # a constant an expression may be derived from (private ones too)
# numbers a derived expression may hold without a source: unit conversions and geometry (halves, 2 pi, dB)
CONVERSION = {0, 1, 2, 3, 4, 10, 20, 1e-6, 1e-3, 1e3, 1e6}


def _modules() -> list[Path]:
    return sorted(SIM.glob("*.py"))


def _is_estimate_call(node: ast.AST) -> bool:
    return (
        isinstance(node, ast.Call)
        and isinstance(node.func, ast.Attribute)
        and node.func.attr == "value"
        and isinstance(node.func.value, ast.Name)
        and node.func.value.id == "estimates"
    )


def _estimate_name(call: ast.Call) -> str | None:
    if (
        len(call.args) == 1
        and not call.keywords
        and isinstance(call.args[0], ast.Constant)
        and isinstance(call.args[0].value, str)
    ):
        return call.args[0].value
    return None


def _walk_outside_estimates(node: ast.AST):
    """`ast.walk`, not descending into `estimates.value(...)` calls."""
    todo = [node]
    while todo:
        n = todo.pop()
        yield n
        if not _is_estimate_call(n):
            todo.extend(ast.iter_child_nodes(n))


def _numbers(node: ast.AST) -> list[float]:
    """The numeric literals of `node` outside estimate calls (dict keys included)."""
    return [
        n.value
        for n in _walk_outside_estimates(node)
        if isinstance(n, ast.Constant) and isinstance(n.value, (int, float, complex)) and not isinstance(n.value, bool)
    ]


def _references(node: ast.AST) -> set[str]:
    """The constants `node` is computed from: UPPER_CASE names and attributes (`archive.FULL_SCALE`)."""
    out = set()
    for n in _walk_outside_estimates(node):
        if isinstance(n, ast.Name) and REFERENCE.match(n.id):
            out.add(n.id)
        elif isinstance(n, ast.Attribute) and REFERENCE.match(n.attr):
            out.add(n.attr)
    return out


def _estimate_calls(tree: ast.AST) -> list[tuple[ast.Call, str | None]]:
    return [(n, _estimate_name(n)) for n in ast.walk(tree) if _is_estimate_call(n)]


def _assignments(tree: ast.Module):
    """(statement, target names, value) of each module-level assignment."""
    for stmt in tree.body:
        if isinstance(stmt, ast.Assign):
            names = [t.id for t in stmt.targets if isinstance(t, ast.Name)]
            yield stmt, names, stmt.value
        elif isinstance(stmt, ast.AnnAssign) and isinstance(stmt.target, ast.Name) and stmt.value is not None:
            yield stmt, [stmt.target.id], stmt.value


def _comments(source: str) -> dict[int, str]:
    """Line number -> the comment on that line."""
    return {
        tok.start[0]: tok.string
        for tok in tokenize.generate_tokens(io.StringIO(source).readline)
        if tok.type == tokenize.COMMENT
    }


def _tag_of(stmt: ast.stmt, lines: list[str], comments: dict[int, str]) -> bool:
    """Whether a source tag sits in a comment on the statement's lines or in the comment block
    directly above it."""
    own = " ".join(comments.get(i, "") for i in range(stmt.lineno, stmt.end_lineno + 1))
    above = []
    i = stmt.lineno - 1
    while i >= 1 and lines[i - 1].lstrip().startswith("#"):
        above.append(lines[i - 1])
        i -= 1
    return bool(SOURCE_TAG.search(own) or SOURCE_TAG.search(" ".join(above)))


def _unsourced(path: Path) -> list[str]:
    source = path.read_text()
    tree = ast.parse(source)
    lines, comments = source.splitlines(), _comments(source)
    bad = []
    for stmt, names, value in _assignments(tree):
        if not any(CONSTANT.match(n) for n in names):
            continue
        numbers = _numbers(value)
        if not numbers:
            continue  # estimates, names, strings
        if _references(value) and all(v in CONVERSION for v in numbers):
            continue  # an expression of other constants (a conversion, a derived geometry)
        if not _tag_of(stmt, lines, comments):
            where = path.relative_to(REPO) if path.is_relative_to(REPO) else path.name
            bad.append(f"{where}:{stmt.lineno} {', '.join(names)} = {ast.unparse(value)[:60]}")
    return bad


def test_every_number_of_the_simulator_is_sourced_or_a_registry_estimate():
    # the registry's own numbers are the estimates' declarations
    bad = [line for path in _modules() if path.name != "estimates.py" for line in _unsourced(path)]
    assert not bad, (
        "module-level numbers with neither a source tag ([paper], [ds], [minsight], [insight], [FACTS], "
        "[cited], [law], "
        "[numerics]) in their comment nor a registry estimate (estimates.value), see calibration's docstring:\n"
        + "\n".join(bad)
    )


def test_the_check_finds_an_unsourced_number(tmp_path):
    code = (
        "X_MM = 3.0  # an estimate without its registry entry\n"
        "# [cited] Someone, 2020\n"
        "Y_MM = 4.0\n"
        "Z_MM = Y_MM * 0.3\n"
        "W_MM = 2 * Y_MM\n"
        'V_MM = (estimates.value("SLIP_PA"), 1.0)  # [numerics]\n'
        'U_MM = (estimates.value("SLIP_PA"), 1.0)\n'
    )
    path = tmp_path / "probe.py"
    path.write_text(code)
    assert [line.split()[0] for line in _unsourced(path)] == ["probe.py:1", "probe.py:4", "probe.py:7"]


# numbers the simulator's code (function and class bodies, default arguments) may hold as they are:
# mathematics (halves, 2 pi, the powers of Hertz's law, trigonometric identities), dB (10, 20),
# unit factors (1e-3 ... 1e9, 60 s per minute, 100 per cent, 180 and 360 degrees, 255 DN of an
# 8-bit pixel), the imaginary unit, small indices and axes, and epsilons guarding a division;
# every other number is a calibration constant, or a numerical setting tagged [numerics] on its line
MATHEMATICAL = {0, 1, 2, 3, 4, 0.5, 10, 20, 60, 100, 180, 255, 360, 1e-3, 1e3, 1e6, 1e9, 1e-6, 1e-9, 1e-12, 1j, 2j}
NUMERICS_TAG = re.compile(r"\[numerics\b")


def _is_constant_assignment(stmt: ast.stmt) -> bool:
    """A module-level assignment to an UPPER_CASE name: `_unsourced` checks its numbers."""
    if isinstance(stmt, ast.Assign):
        return any(isinstance(t, ast.Name) and CONSTANT.match(t.id) for t in stmt.targets)
    return (
        isinstance(stmt, ast.AnnAssign) and isinstance(stmt.target, ast.Name) and bool(CONSTANT.match(stmt.target.id))
    )


def _unexplained_literals(path: Path) -> list[str]:
    """The numeric literals outside module-level constants (in function and class bodies, default
    arguments, decorators) that are neither in `MATHEMATICAL` nor on a line tagged [numerics]."""
    source = path.read_text()
    comments = _comments(source)
    bad = []
    for stmt in ast.parse(source).body:
        if _is_constant_assignment(stmt):
            continue
        for n in ast.walk(stmt):
            if (
                not isinstance(n, ast.Constant)
                or isinstance(n.value, bool)
                or not isinstance(n.value, (int, float, complex))
            ):
                continue
            if n.value in MATHEMATICAL or NUMERICS_TAG.search(comments.get(n.lineno, "")):
                continue
            where = path.relative_to(REPO) if path.is_relative_to(REPO) else path.name
            bad.append(f"{where}:{n.lineno} {n.value!r}")
    return bad


def test_no_magnitude_is_written_into_the_simulators_code():
    bad = [line for path in _modules() for line in _unexplained_literals(path)]
    assert not bad, (
        "numbers in the simulator's functions that are neither mathematics (MATHEMATICAL) nor a numerical "
        "setting tagged "
        "[numerics] on their line: make each a calibration constant (sourced, or a registry estimate) and "
        "read it as cal.NAME:\n" + "\n".join(bad)
    )


def test_the_literal_check_finds_a_magnitude_in_a_function(tmp_path):
    code = (
        "SPREAD_DB = 0.3  # [cited] module-level: the other check's\n"
        "def jitter(rng, x=0.7):\n"
        "    a = rng.uniform(-0.3, 0.3)\n"
        "    b = 2 * np.pi * 1e-3 * 0.5 * x\n"
        "    c = np.zeros(256)  # [numerics] a grid\n"
        "    return a * 10 ** (b / 20) * -1.5\n"
        "class Probe:\n"
        "    n: int = 50\n"
    )
    path = tmp_path / "probe.py"
    path.write_text(code)
    assert _unexplained_literals(path) == [
        "probe.py:2 0.7",
        "probe.py:3 0.3",
        "probe.py:3 0.3",
        "probe.py:6 1.5",
        "probe.py:8 50",
    ]


def test_estimate_calls_name_registry_estimates():
    unknown = [
        f"{path.relative_to(REPO)}:{call.lineno} {ast.unparse(call)}"
        for path in _modules()
        for call, name in _estimate_calls(ast.parse(path.read_text()))
        if name not in estimates.ESTIMATES
    ]
    assert not unknown, "estimates.value of a name the registry lacks (or not a string literal):\n" + "\n".join(unknown)


def test_each_estimate_is_named_once_and_calibration_holds_every_one():
    """The registry is the one place an estimate is named: calibration holds it as a constant of
    that name without assigning one, or reads it (`element_of`) where it builds the constant it is
    an element of."""
    tree = ast.parse((SIM / "calibration.py").read_text())
    assigned = {name for _, names, _ in _assignments(tree) for name in names}
    renamed = sorted(assigned & set(estimates.ESTIMATES))
    assert not renamed, f"calibration.py assigns a constant an estimate's name (the registry binds it): {renamed}"
    read = {name for _, name in _estimate_calls(tree)}
    for e in estimates.ESTIMATES.values():
        if e.element_of is None:
            assert getattr(cal, e.name) == estimates.value(e.name), e.name
        else:
            assert e.name in read and e.element_of in assigned, (e.name, e.element_of)
            assert not hasattr(cal, e.name), e.name


def test_every_estimate_is_declared_within_its_range_with_a_reason():
    assert len(estimates.GROUPS) >= 2, estimates.GROUPS  # a screening needs two factors
    for e in estimates.ESTIMATES.values():
        assert e.low <= e.value <= e.high and e.low < e.high, e
        assert e.reason.strip() and e.drives.strip() and e.group.strip(), e.name
        assert e.streams and set(e.streams) <= set(estimates.STREAMS), e.name
        assert len(set(e.streams)) == len(e.streams), e.name
        assert not e.log or e.low > 0, e.name
        assert estimates.value(e.name) == e.value  # nothing overridden outside a scene
        assert e.at(e.place()) == pytest.approx(e.value, rel=1e-12, abs=1e-15)


def _calibration_aliases(tree: ast.Module) -> tuple[set[str], set[str]]:
    """(names bound to the calibration module, names imported from it) at module level."""
    modules, names = set(), set()
    for stmt in tree.body:
        if isinstance(stmt, ast.ImportFrom) and stmt.module == "fabricjax.sim":
            modules |= {a.asname or a.name for a in stmt.names if a.name == "calibration"}
        elif isinstance(stmt, ast.ImportFrom) and stmt.module == "fabricjax.sim.calibration":
            names |= {a.name for a in stmt.names}
        elif isinstance(stmt, ast.Import):
            modules |= {a.asname for a in stmt.names if a.name == "fabricjax.sim.calibration" and a.asname}
    return modules, names


def _estimate_derived() -> set[str]:
    """calibration's module-level names computed from an estimate (directly or through another)."""
    derived = set(estimates.constants())
    for _, names, value in _assignments(ast.parse((SIM / "calibration.py").read_text())):
        if _estimate_calls(value) or any(isinstance(n, ast.Name) and n.id in derived for n in ast.walk(value)):
            derived |= set(names)
    return derived


def _import_time_nodes(body: list[ast.stmt]):
    """The nodes a module executes when imported: not function bodies (their defaults and
    decorators, yes), class bodies yes."""
    for stmt in body:
        if isinstance(stmt, (ast.FunctionDef, ast.AsyncFunctionDef)):
            args = stmt.args
            for n in [*stmt.decorator_list, *args.defaults, *[d for d in args.kw_defaults if d is not None]]:
                yield from ast.walk(n)
        elif isinstance(stmt, ast.ClassDef):
            for n in [*stmt.decorator_list, *stmt.bases, *[k.value for k in stmt.keywords]]:
                yield from ast.walk(n)
            yield from _import_time_nodes(stmt.body)
        else:
            todo = [stmt]
            while todo:
                n = todo.pop()
                yield n
                todo.extend(c for c in ast.iter_child_nodes(n) if not isinstance(c, ast.Lambda))


def test_no_module_but_calibration_computes_from_an_estimate_at_import():
    """`trial.use_estimates` executes calibration again; a module that copied an estimate (or a
    constant derived from one) when it was imported would keep the old value."""
    derived = _estimate_derived()
    assert {"TEXTURE_PA_PER_UM", "SPEAKER_DISTANCE_M", "CAMERA_HALF_FOV_RAD", "SEATING_ROTATION_SD_RAD"} <= derived
    bad = []
    for path in _modules():
        if path.name == "calibration.py":
            continue
        tree = ast.parse(path.read_text())
        aliases, imported = _calibration_aliases(tree)
        bad += [f"{path.relative_to(REPO)}: from calibration import {n}" for n in sorted(imported & derived)]
        bad += [
            f"{path.relative_to(REPO)}:{n.lineno} {ast.unparse(n)}"
            for n in _import_time_nodes(tree.body)
            if isinstance(n, ast.Attribute)
            and isinstance(n.value, ast.Name)
            and n.value.id in aliases
            and n.attr in derived
        ]
    assert not bad, (
        "module-level uses of estimate-derived calibration constants (compute them at the use site):\n" + "\n".join(bad)
    )


def _same(a, b) -> bool:
    arrays_a, arrays_b = a.arrays(), b.arrays()
    return (
        a.meta == b.meta
        and arrays_a.keys() == arrays_b.keys()
        and all(
            arrays_a[k].dtype == arrays_b[k].dtype
            and arrays_a[k].shape == arrays_b[k].shape
            and arrays_a[k].tobytes() == arrays_b[k].tobytes()
            for k in arrays_a
        )
    )


def test_an_override_changes_the_data_and_going_back_restores_it_byte_for_byte():
    scene = Scene(fabric_id=1, cycles=1, streams=("audio", "proprio"))
    published = trial.simulate(scene)
    loud = trial.simulate(
        Scene(
            fabric_id=1,
            cycles=1,
            streams=("audio", "proprio"),
            estimates=(("SERVO_TONE_PA", estimates.ESTIMATES["SERVO_TONE_PA"].high),),
        )
    )
    assert not np.array_equal(loud.audio, published.audio)
    np.testing.assert_array_equal(loud.joints, published.joints)  # an audio estimate leaves the joints alone
    again = trial.simulate(scene)
    assert _same(again, published)
    assert cal.SERVO_TONE_PA == estimates.ESTIMATES["SERVO_TONE_PA"].value


def test_constants_derived_from_an_estimate_follow_it():
    area, far = estimates.ESTIMATES["CONTACT_AREA_M2"], estimates.ESTIMATES["SPEAKER_DISTANCE_FAR_M"]
    published = (cal.TEXTURE_PA_PER_UM, cal.CLOTH_RADIATOR_RADIUS_M, cal.SPEAKER_DISTANCE_M)
    try:
        trial.use_estimates((("CONTACT_AREA_M2", area.high), ("SPEAKER_DISTANCE_FAR_M", far.low)))
        assert cal.TEXTURE_PA_PER_UM == pytest.approx(published[0] * area.high / area.value)
        assert cal.CLOTH_RADIATOR_RADIUS_M > published[1]
        assert cal.SPEAKER_DISTANCE_M == (published[2][0], far.low)
    finally:
        trial.use_estimates(())
    assert (cal.TEXTURE_PA_PER_UM, cal.CLOTH_RADIATOR_RADIUS_M, cal.SPEAKER_DISTANCE_M) == published


@pytest.mark.parametrize("values", [(("SERVO_TONE_PA", 1.0),), (("SERVO_TONE_PA", 0.0),), (("NOT_AN_ESTIMATE", 1.0),)])
def test_a_scene_with_an_estimate_out_of_range_or_unknown_is_refused(values):
    with pytest.raises(ValueError):
        Scene(fabric_id=1, estimates=values)


def test_the_documented_table_is_the_registry():
    doc = (REPO / "docs" / "simulator.md").read_text()
    assert estimates.with_table(doc) == doc, (
        "docs/simulator.md's estimates table differs: run python -m experiments.estimates"
    )
    for name in estimates.ESTIMATES:
        assert f"`{name}`" in doc


def test_the_catalog_scales_apply_to_every_fabric_alike_and_leave_class_0_and_the_catalog_itself():
    from fabricjax import catalog
    from fabricjax.sim.scene import CATALOG_SCALES, simulated_fabric

    assert all(estimates.ESTIMATES[name].value == 1.0 for name in CATALOG_SCALES.values())
    assert simulated_fabric(3) is catalog.fabric(3)  # the published data: the catalog's own entry
    high = {name: estimates.ESTIMATES[name].high for name in CATALOG_SCALES.values()}
    try:
        trial.use_estimates(tuple(sorted(high.items())))
        for field, name in CATALOG_SCALES.items():
            assert getattr(simulated_fabric(3), field) == pytest.approx(getattr(catalog.fabric(3), field) * high[name])
        assert simulated_fabric(0) is catalog.fabric(0)  # no fabric: the fingers rub each other
    finally:
        trial.use_estimates(())
    assert simulated_fabric(3) is catalog.fabric(3)
