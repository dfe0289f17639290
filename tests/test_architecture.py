"""The layers and contracts the code promises (issue 16), checked on the source itself."""

import ast
from pathlib import Path

import pytest

from rbenvs.contracts import Integrator, StepRegion, System, Task, require_parts
from rbenvs.envs import FreeRigidBodyEnv, LagrangeTopEnv, TippeTopEnv
from rbenvs.integrators import INTEGRATORS

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "rbenvs"


def _trees(folder: Path, pattern="*.py"):
    for path in sorted(folder.rglob(pattern)):
        if "__pycache__" not in path.parts:
            yield path, ast.parse(path.read_text(), filename=str(path))


# A name with a leading underscore read off an object other than ``self``/``cls``: allowed for
# namedtuple's public methods, the interpreter's frame, and numba's caching internals in the one
# module whose job they are.
_PRIVATE_ALLOWED = {
    ("*", "_make"),
    ("*", "_replace"),
    ("*", "_fields"),
    ("*", "_asdict"),
    ("rbenvs/envs/base.py", "_getframe"),  # (the caller's line in a warning)
    ("rbenvs/kernel_cache.py", "_cache"),  # (numba's cache hook on a dispatcher)
    ("rbenvs/kernel_cache.py", "_rebuild"),  # (a compile result rebuilt from disk)
    ("rbenvs/kernel_cache.py", "_reduce"),  # (a compile result's serialisable parts)
}


def test_no_module_reads_a_private_attribute_of_another_object():
    """rbenvs/ drives its parts through public names only (issue 45): ``x._name`` is allowed for
    ``self`` and ``cls`` alone, namedtuple's methods and the listed internals of Python and numba
    aside."""
    offences = []
    for path, tree in _trees(PACKAGE):
        rel = path.relative_to(ROOT).as_posix()
        for node in ast.walk(tree):
            if (
                isinstance(node, ast.Attribute)
                and node.attr.startswith("_")
                and not node.attr.startswith("__")
                and not (isinstance(node.value, ast.Name) and node.value.id in ("self", "cls"))
                and ("*", node.attr) not in _PRIVATE_ALLOWED
                and (rel, node.attr) not in _PRIVATE_ALLOWED
            ):
                offences.append(f"{rel}:{node.lineno} {ast.unparse(node)}")
    assert not offences, offences


# getattr/hasattr with a literal name: a probe of an outside object's optional attribute,
# allowed for these alone (none a part's capability: those are declared in rbenvs.contracts and
# rbenvs.verify.protocol and read as attributes, or checked as sub-Protocols)
_PROBES_ALLOWED = {
    "episodes": "argparse: the subcommands' namespaces differ",
    "_is_protocol": "typing's marker of a Protocol class",
    "py_func": "a numba dispatcher's Python function, hashed into the kernel cache's key",
    "_started": "kernel_cache's own timer, set once compiling starts",
    "isatty": "a stream, which may be any file-like object",
    "unwrapped": "a gymnasium env or a wrapper of one",
    "item": "a numpy scalar or a Python number",
    "register_at_fork": "os, on a platform without fork",
}


def test_no_capability_is_probed():
    """No ``getattr``/``hasattr`` of a literal name in rbenvs/ but the listed outside ones and
    Python's dunders (issue 45): a part's optional capabilities are declared (the contracts'
    members, a system's ``provides``, the verify protocol's sub-Protocols) and checked once, at
    construction."""
    from rbenvs import contracts
    from rbenvs.verify import protocol

    declared = set()
    for module in (contracts, protocol):
        for value in vars(module).values():
            if isinstance(value, type) and getattr(value, "_is_protocol", False):
                declared |= set(contracts._members(value))
    offences = []
    for path, tree in _trees(PACKAGE):
        for node in ast.walk(tree):
            if (
                isinstance(node, ast.Call)
                and isinstance(node.func, ast.Name)
                and node.func.id in ("getattr", "hasattr")
                and len(node.args) >= 2
                and isinstance(node.args[1], ast.Constant)
            ):
                name = node.args[1].value
                dunder = name.startswith("__") and name.endswith("__")
                if name in declared or not (dunder or name in _PROBES_ALLOWED):
                    offences.append(f"{path.relative_to(ROOT)}:{node.lineno} {name}")
    assert not offences, offences
    assert {"kernel_rhs", "kernel_rhs_event", "error_constant", "batched"} <= declared


def test_exec_appears_in_one_module_only():
    """Generated code is compiled in rbenvs/codegen.py alone."""
    users = set()
    for path, tree in _trees(PACKAGE):
        for node in ast.walk(tree):
            if (
                isinstance(node, ast.Call)
                and isinstance(node.func, ast.Name)
                and node.func.id in ("exec", "eval")
            ):
                users.add(path.relative_to(ROOT).as_posix())
    assert users == {"rbenvs/codegen.py"}, users


def _module_imports() -> dict:
    """Every module of rbenvs/ and the modules of rbenvs/ it imports, at the top or inside a
    function alike (a lazy import is still a dependency): ``{"rbenvs.core.step": {...}}``."""
    modules = {}
    for path, _ in _trees(PACKAGE):
        parts = list(path.relative_to(ROOT).with_suffix("").parts)
        modules[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = path
    graph = {}
    for name, path in modules.items():
        package = name if path.name == "__init__.py" else name.rsplit(".", 1)[0]
        deps = set()
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom):
                base = (
                    package.split(".")[: len(package.split(".")) - node.level + 1]
                    if node.level
                    else []
                )
                target = ".".join(base + ([node.module] if node.module else []))
                candidates = [target] + [f"{target}.{alias.name}" for alias in node.names]
            elif isinstance(node, ast.Import):
                candidates = [alias.name for alias in node.names]
            else:
                continue
            deps.update(c for c in candidates if c in modules and c != name)
        graph[name] = deps
    return graph


def test_the_bottom_layer_imports_nothing_above_it():
    """Code generation and the contracts are the bottom layer (issue 45): every layer may use
    them, and they import nothing from rbenvs."""
    graph = _module_imports()
    for bottom in ("rbenvs.codegen", "rbenvs.contracts"):
        assert graph[bottom] == set(), (bottom, graph[bottom])


def test_the_core_imports_no_compiled_code():
    """The compiled code is a backend (issue 45): the step core and the step controller are
    given a loader of it (rbenvs.contracts.CompiledBackend) and import neither rbenvs.compiled
    nor the kernel cache, whose modules import the core."""
    graph = _module_imports()
    for name, deps in graph.items():
        if name.startswith(("rbenvs.core", "rbenvs.stepsize")):
            compiled = {d for d in deps if d.startswith(("rbenvs.compiled", "rbenvs.kernel_cache"))}
            assert not compiled, (name, compiled)


def test_the_step_reaches_the_controller_through_its_objects():
    """The step controller's pure forms (rbenvs.stepsize.forms: the counts and estimates as
    functions) are its own and its compiled form's (issue 44): the engine, the envs and the
    vector env take its decisions through its objects (StepRule, GlobalErrorCheck,
    BatchAccuracy) and its settings, never from the forms; bench/ and verify/ measure them."""
    graph = _module_imports()
    allowed = ("rbenvs.stepsize", "rbenvs.compiled", "rbenvs.bench", "rbenvs.verify")
    users = {name for name, deps in graph.items() if "rbenvs.stepsize.forms" in deps} - {
        name for name in graph if name.startswith(allowed)
    }
    assert not users, users


def test_no_import_cycle_in_rbenvs():
    """No module of rbenvs/ reaches itself through its imports (issue 44): each layer imports
    only below it, so a module can be read, tested and changed without the ones above it."""
    graph = _module_imports()
    cycles, done = [], set()

    def visit(name, path):
        if name in path:
            cycles.append(path[path.index(name) :] + [name])
            return
        if name in done:
            return
        for dep in sorted(graph[name]):
            visit(dep, path + [name])
        done.add(name)

    for name in sorted(graph):
        visit(name, [])
    assert not cycles, cycles


def test_nothing_in_rbenvs_imports_the_agents():
    for path, tree in _trees(PACKAGE):
        for node in ast.walk(tree):
            names = (
                [a.name for a in node.names]
                if isinstance(node, ast.Import)
                else [node.module or ""]
                if isinstance(node, ast.ImportFrom)
                else []
            )
            assert not any(n.split(".")[0] == "rbenvs_agents" for n in names), (path, node.lineno)


def test_bench_and_verify_use_each_others_public_names_only():
    for folder, other in (("bench", "verify"), ("verify", "bench")):
        for path, tree in _trees(PACKAGE / folder):
            for node in ast.walk(tree):
                if (
                    isinstance(node, ast.ImportFrom)
                    and node.module
                    and (
                        other in node.module.split(".")
                        or node.level
                        and node.module.split(".")[0] in (folder, other)
                    )
                ):
                    private = [a.name for a in node.names if a.name.startswith("_")]
                    assert not private, (path, node.lineno, private)


def test_tests_share_helpers_through_conftest_not_each_other():
    for path, tree in _trees(ROOT / "tests", "test_*.py"):
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom) and node.module:
                assert not node.module.startswith("test_"), (path, node.lineno, node.module)
            if isinstance(node, ast.Import):
                assert not any(a.name.startswith("test_") for a in node.names), (path, node.lineno)


@pytest.mark.parametrize("name", sorted(INTEGRATORS))
def test_every_integrator_declares_its_contract_and_region(name):
    integ = INTEGRATORS[name]()
    require_parts(integ, Integrator, "integrator")
    assert isinstance(integ.region, StepRegion) and integ.region.reason


class _NoRegion(INTEGRATORS["rk4"]):
    region = None


def test_an_integrator_without_a_region_cannot_run():
    with pytest.raises(ValueError, match="step region"):
        FreeRigidBodyEnv(integrator=_NoRegion())


@pytest.mark.parametrize(
    "env",
    [
        FreeRigidBodyEnv(),
        FreeRigidBodyEnv(task="reorient"),
        LagrangeTopEnv(task="precess", attitude=True),
        TippeTopEnv(free_flight=True),
    ],
    ids=["free", "reorient", "precess", "tippe"],
)
def test_every_system_and_task_provides_its_contract(env):
    require_parts(env.system, System, "system")
    require_parts(env.task, Task, "task")
    assert (
        len(env.task.observation_names)
        == len(env.task.observation_units)
        == env.observation_space.shape[0]
    )
    assert env.task.metric_names[-1] == "is_success"


def test_require_parts_names_what_is_missing():
    class Half:
        dim, layout, readout_names = 3, {}, ()

    with pytest.raises(TypeError, match="rhs"):
        require_parts(Half(), System, "system")


def test_a_registered_scheme_is_in_every_env_it_supports_and_verify_reports_it_unverified(
    monkeypatch,
):
    """A new integrator registered once appears in the choices of every env whose system meets
    its needs, runs guarded by its own region, and `rbenvs verify` reports it as unverified
    (a FAIL row) until it has settings, rather than skipping it."""
    from dataclasses import dataclass

    from rbenvs import integrators, verify

    @dataclass(frozen=True)
    class RK4Copy(integrators.RK4):
        name = "rk4_copy"

    monkeypatch.setitem(integrators.INTEGRATORS, "rk4_copy", RK4Copy)
    assert all(
        "rk4_copy" in cls.integrators for cls in (FreeRigidBodyEnv, LagrangeTopEnv, TippeTopEnv)
    )
    env = FreeRigidBodyEnv(
        integrator="rk4_copy", spin_rate=30.0, max_angular_velocity=200.0, task="detumble"
    )
    assert env.step_rule.active and env.step_rule.params[1] == 1.0  # the region RK4Copy declares
    rows = verify.run_checks(
        systems=("free_body", "tippe_top"),
        integrators=["rk4_copy"],
        quick=True,
        show_progress=False,
    )
    assert [(r.system, r.passed) for r in rows if "verification settings" in r.check] == [
        ("free_body", False),
        ("tippe_top", False),
    ]


def test_vector_classes_come_from_the_registration():
    from rbenvs import vector

    for _env_id, cls in (
        ("rbenvs/FreeRigidBody-v0", FreeRigidBodyEnv),
        ("rbenvs/LagrangeTop-v0", LagrangeTopEnv),
        ("rbenvs/TippeTop-v0", TippeTopEnv),
    ):
        vcls = vector.vector_class(cls)
        assert vcls.env_class is cls and vcls.__name__ == cls.__name__.replace("Env", "VectorEnv")
        assert getattr(vector, vcls.__name__) is vcls
    with pytest.raises(AttributeError):
        vector.NoSuchVectorEnv  # noqa: B018


def test_every_name_read_off_a_module_of_rbenvs_exists():
    """A name imported from a module of rbenvs, or read off one as an attribute (``module.name``,
    ``alias.name``), exists there: a module split into a package keeps what its readers read (the
    linter sees undefined names, not missing attributes of another module)."""
    import importlib

    modules = {}
    for path, _ in _trees(PACKAGE):
        parts = list(path.relative_to(ROOT).with_suffix("").parts)
        modules[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = path
    reads = set()
    sources = list(_trees(PACKAGE)) + list(_trees(ROOT / "tests", "*.py"))
    sources += list(_trees(ROOT / "agents"))
    for path, tree in sources:
        rel = path.relative_to(ROOT)
        parts = list(rel.with_suffix("").parts)
        package = ".".join(parts[:-1]) if parts[-1] != "__init__" else ".".join(parts[:-1])
        aliases = {}
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom):
                base = (
                    package.split(".")[: len(package.split(".")) - node.level + 1]
                    if node.level
                    else []
                )
                source = ".".join(base + ([node.module] if node.module else []))
                for alias in node.names:
                    if f"{source}.{alias.name}" in modules:
                        aliases[alias.asname or alias.name] = f"{source}.{alias.name}"
                    elif source in modules and alias.name != "*":
                        reads.add((source, alias.name, f"{rel}:{node.lineno}"))
            elif isinstance(node, ast.Import):
                for alias in node.names:
                    if alias.asname and alias.name in modules:
                        aliases[alias.asname] = alias.name
        for node in ast.walk(tree):
            if (
                isinstance(node, ast.Attribute)
                and isinstance(node.value, ast.Name)
                and node.value.id in aliases
            ):
                reads.add((aliases[node.value.id], node.attr, f"{rel}:{node.lineno}"))
    missing = []
    for source, name, where in sorted(reads):
        module = importlib.import_module(source)
        if name.startswith("NoSuch"):  # (a test's deliberate miss)
            continue
        if not hasattr(module, name) and f"{source}.{name}" not in modules:
            missing.append(f"{where}: {source}.{name}")
    assert not missing, missing
