"""The on-disk kernel cache (rbenvs.kernel_cache): a second process loads what the first compiled
(counted, not timed), a file that does not verify is compiled again, processes compiling one
kernel at once, a folder that cannot be written, and the fingerprint that keys a kernel."""

import json
import os
import subprocess
import sys
import warnings

import numpy as np
import pytest

from rbenvs import kernel_cache

pytest.importorskip("numba")

# A fresh process: makes and steps an env (or a vector env), prints the cache's counts and the
# step's observation (to compare across processes: a loaded kernel computes what a compiled one
# does), and the kernels' labels. env_id "small": a small generated kernel instead (through the same
# rbenvs.kernel_cache.njit), n its constant: the tests of the files' handling need a kernel, not an
# env's seconds of compiling
SCRIPT = r"""
import json, sys, warnings
import numpy as np
from rbenvs import kernel_cache
env_id, n, threads = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
with warnings.catch_warnings(record=True) as caught:
    warnings.simplefilter("always")
    if env_id == "small":
        from rbenvs.codegen import generate
        f = kernel_cache.njit(
            generate("def f(x):\n    return x * K + 1.0\n", "cache test", {"K": float(n)})["f"],
            "cache test",
        )
        obs = [f(0.3 * j) for j in range(3)]
    else:
        import gymnasium as gym
        import rbenvs
        if n:
            env = gym.make_vec(env_id, num_envs=n, vectorization_mode="vector_entry_point",
                               num_threads=threads)
        else:
            env = gym.make(env_id)
        env.reset(seed=3)
        obs = None
        for _ in range(3):
            obs = env.step(np.full(env.action_space.shape, 0.3, dtype=env.action_space.dtype))[0]
print(json.dumps({"stats": kernel_cache.stats(), "obs": np.asarray(obs).tolist(),
                  "labels": [k[0] for k in kernel_cache.kernels()],
                  "warnings": [str(w.message) for w in caught
                               if issubclass(w.category, kernel_cache.KernelCacheWarning)]}))
"""


def run(cache_dir, env_id="small", n=1, threads=1):
    env = dict(os.environ, RBENVS_CACHE_DIR=str(cache_dir))
    out = subprocess.run(
        [sys.executable, "-c", SCRIPT, env_id, str(n), str(threads)],
        env=env,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert out.returncode == 0, out.stderr
    return json.loads(out.stdout.strip().splitlines()[-1])


def kernel_files(cache_dir):
    """The kernel files (beside each one compiled, its empty compile lock: not a kernel)."""
    return sorted(
        p for p in (cache_dir / "kernels").rglob("*") if p.is_file() and p.suffix != ".lock"
    )


def test_a_second_process_loads_what_the_first_compiled(tmp_path):
    first = run(tmp_path, "rbenvs/FreeRigidBody-v0", 0)
    assert first["stats"]["compiled"] >= 1 and first["stats"]["loaded"] == 0
    assert first["stats"]["saved"] == first["stats"]["compiled"]
    files = kernel_files(tmp_path)
    assert len(files) == first["stats"]["saved"] and all(p.suffix == ".nbk" for p in files)
    second = run(tmp_path, "rbenvs/FreeRigidBody-v0", 0)
    assert second["stats"] == {
        "loaded": first["stats"]["compiled"],
        "compiled": 0,
        "rejected": 0,
        "saved": 0,
    }
    assert second["obs"] == first["obs"]  # bit for bit (JSON keeps every float's digits)
    assert not first["warnings"] and not second["warnings"]


def test_a_vector_env_its_split_step_and_generator_table_load_too(tmp_path):
    # num_threads=2 on 128 sub-envs: the step split into two chunks (a parallel kernel over the
    # one-call step), the generator table's two kernels (make, append)
    first = run(tmp_path, "rbenvs/FreeRigidBody-v0", 128, threads=2)
    assert first["labels"].count("vsplit") == 1 and first["labels"].count("vstep") == 1
    assert first["stats"]["compiled"] >= 4
    second = run(tmp_path, "rbenvs/FreeRigidBody-v0", 128, threads=2)
    # (the loaded split step carries the one-call step's code: nothing else to load)
    assert second["stats"]["compiled"] == 0 and "vsplit" in second["labels"]
    assert second["stats"]["loaded"] == first["stats"]["compiled"] - 1
    assert second["obs"] == first["obs"]
    # an unthreaded env loads the one-call step the threaded one compiled
    one_call = run(tmp_path, "rbenvs/FreeRigidBody-v0", 128)
    assert one_call["stats"]["compiled"] == 0 and "vstep" in one_call["labels"]
    assert one_call["obs"] == first["obs"]


# Both autoreset modes, and a pickled and a deep-copied env of each, in a fresh process: numba
# compiles one specialization per argument types, a read-only array's type not a writable one's,
# so one mode passing a shared read-only mask where the other passes its own array, or pickle
# giving the shared masks back writable, compiled the whole step again (three times in all)
MODES_SCRIPT = r"""
import copy, json, pickle
import gymnasium as gym
import numpy as np
from gymnasium.vector import AutoresetMode
import rbenvs
from rbenvs import kernel_cache
obs = []
for mode in (AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP):
    env = gym.make_vec("rbenvs/FreeRigidBody-v0", num_envs=4,
                       vectorization_mode="vector_entry_point", autoreset_mode=mode)
    env.reset(seed=3)
    for e in (env, pickle.loads(pickle.dumps(env)), copy.deepcopy(env)):
        obs.append(e.step(np.full(env.action_space.shape, 0.3, dtype=np.float32))[0].tolist())
print(json.dumps({"labels": [k[0] for k in kernel_cache.kernels() if k[2] == "compiled"],
                  "obs": obs}))
"""


def test_both_autoreset_modes_and_pickled_copies_share_one_compiled_step(tmp_path):
    env = dict(os.environ, RBENVS_CACHE_DIR=str(tmp_path))
    out = subprocess.run(
        [sys.executable, "-c", MODES_SCRIPT], env=env, capture_output=True, text=True, timeout=600
    )
    assert out.returncode == 0, out.stderr
    result = json.loads(out.stdout.strip().splitlines()[-1])
    assert result["labels"].count("vstep") == 1, result["labels"]
    # each mode's copies go on from the same state with the same bits
    assert result["obs"][1] == result["obs"][2] == result["obs"][0]
    assert result["obs"][4] == result["obs"][5] == result["obs"][3]


# After `rbenvs warmup`, a fresh process's default envs compile nothing, whether its actions are
# float32 (the action space's, a policy's) or float64 (numpy's, a controller's): numba types the
# two apart, so a warm-up that stepped one of them left the other's first step compiling
FIRST_STEPS_SCRIPT = r"""
import json
import gymnasium as gym
import numpy as np
import rbenvs
from rbenvs import kernel_cache
for env in (gym.make("rbenvs/FreeRigidBody-v0"),
            gym.make_vec("rbenvs/FreeRigidBody-v0", num_envs=16,
                         vectorization_mode="vector_entry_point")):
    env.reset(seed=1)
    env.step(env.action_space.sample())
    env.step(np.full(env.action_space.shape, 0.25))
print(json.dumps(kernel_cache.stats()))
"""


def test_after_warmup_the_default_envs_first_steps_compile_nothing(tmp_path):
    env = dict(os.environ, RBENVS_CACHE_DIR=str(tmp_path))
    warm = [sys.executable, "-m", "rbenvs", "warmup", "--system", "free_body", "--no-progress"]
    out = subprocess.run(warm, env=env, capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stderr
    out = subprocess.run(
        [sys.executable, "-c", FIRST_STEPS_SCRIPT],
        env=env,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert out.returncode == 0, out.stderr
    stats = json.loads(out.stdout.strip().splitlines()[-1])
    assert stats["compiled"] == 0 and stats["loaded"] >= 2, stats


@pytest.mark.parametrize("damage", ["truncate", "flip", "empty", "swap"])
def test_a_file_that_does_not_verify_is_compiled_again_not_loaded(tmp_path, damage):
    first = run(tmp_path)
    files = kernel_files(tmp_path)
    blobs = [p.read_bytes() for p in files]
    for p, blob in zip(files, blobs):
        if damage == "truncate":
            p.write_bytes(blob[: len(blob) // 2])
        elif damage == "flip":  # one bit in the object code's half, the length kept
            k = len(blob) * 3 // 4
            p.write_bytes(blob[:k] + bytes([blob[k] ^ 0x10]) + blob[k + 1 :])
        elif damage == "empty":
            p.write_bytes(b"")
    if damage == "swap":  # a whole, valid file of another kernel under this one's name
        other = run(tmp_path, "small", 2)
        assert other["stats"]["compiled"] >= 1
        theirs = sorted(set(kernel_files(tmp_path)) - set(files))
        files[0].write_bytes(theirs[0].read_bytes())
    second = run(tmp_path)
    assert second["stats"]["rejected"] >= 1
    assert second["stats"]["compiled"] == second["stats"]["rejected"]
    assert second["obs"] == first["obs"]
    third = run(tmp_path)  # the damaged files were overwritten with good ones
    assert third["stats"]["compiled"] == 0 and third["stats"]["rejected"] == 0
    assert third["obs"] == first["obs"]


def test_four_processes_compiling_one_kernel_at_once_compile_it_once(tmp_path):
    env = dict(os.environ, RBENVS_CACHE_DIR=str(tmp_path))
    procs = [
        subprocess.Popen(
            [sys.executable, "-c", SCRIPT, "small", "1", "1"],
            env=env,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        for _ in range(4)
    ]
    results = []
    for p in procs:
        out, err = p.communicate(timeout=600)
        assert p.returncode == 0, err
        results.append(json.loads(out.strip().splitlines()[-1]))
    assert all(r["obs"] == results[0]["obs"] for r in results)
    assert not any(r["warnings"] for r in results)
    # one compiles, holding the kernel's lock; the others wait for its file and load it
    assert sum(r["stats"]["compiled"] for r in results) == 1
    assert sum(r["stats"]["loaded"] for r in results) == 3
    assert not [
        p for p in (tmp_path / "kernels").rglob("*") if ".tmp." in p.name
    ]  # no partial file left
    after = run(tmp_path)
    assert (
        after["stats"]["compiled"] == 0
        and after["stats"]["rejected"] == 0
        and after["obs"] == results[0]["obs"]
    )


def test_a_folder_that_cannot_be_written_compiles_in_memory_with_one_warning(tmp_path):
    blocker = tmp_path / "a-file"
    blocker.write_text(
        "not a folder"
    )  # (root may write anywhere: a file in the path stops everyone)
    out = run(blocker / "cache")
    assert len(out["warnings"]) == 1 and "compiled in memory" in out["warnings"][0]
    assert out["stats"]["compiled"] >= 1 and out["stats"]["saved"] == 0
    reference = run(tmp_path / "good")
    assert out["obs"] == reference["obs"]


def test_a_full_disk_turns_the_cache_off_with_one_warning(tmp_path, monkeypatch):
    # in this process: the write fails as on a full disk (ENOSPC); the kernel still runs, compiled
    # in memory
    import errno

    monkeypatch.setenv(kernel_cache.CACHE_VARIABLE, str(tmp_path))
    monkeypatch.setattr(kernel_cache, "_off_reason", [])

    def full(*args, **kwargs):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(kernel_cache.os, "replace", full)

    def add(x, y):
        return x + 2.0 * y

    def sub(x, y):
        return x - 2.0 * y

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        assert kernel_cache.njit(add, "test add")(1.0, 2.0) == 5.0
        assert kernel_cache.njit(sub, "test sub")(1.0, 2.0) == -3.0
    messages = [w for w in caught if issubclass(w.category, kernel_cache.KernelCacheWarning)]
    assert len(messages) == 1 and "No space left" in str(messages[0].message)
    assert not list(tmp_path.rglob("*.nbk")) and not [
        p for p in tmp_path.rglob("*") if ".tmp." in p.name
    ]


def test_numbas_optimisation_level_and_bounds_checking_key_their_own_folder():
    """NUMBA_OPT and NUMBA_BOUNDSCHECK change the code numba emits (bounds checking also what
    it raises): a process under either loads nothing another process compiled without it."""
    here = kernel_cache.environment()["numba_settings"]
    code = "from rbenvs import kernel_cache; print(kernel_cache.environment()['numba_settings'])"
    for variable, value in (("NUMBA_OPT", "0"), ("NUMBA_BOUNDSCHECK", "1")):
        env = dict(os.environ, **{variable: value})
        out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True)
        assert out.returncode == 0, out.stderr
        assert out.stdout.strip() != str(here), (variable, out.stdout, here)


def test_an_empty_cache_variable_turns_the_disk_cache_off(monkeypatch):
    monkeypatch.setenv(kernel_cache.CACHE_VARIABLE, "")
    assert kernel_cache.cache_root() is None and kernel_cache.kernel_folder() is None


def test_the_default_folder_is_the_platforms_cache(monkeypatch, tmp_path):
    monkeypatch.delenv(kernel_cache.CACHE_VARIABLE, raising=False)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    if sys.platform.startswith("linux"):
        assert kernel_cache.cache_root() == tmp_path / "rbenvs"
    folder = kernel_cache.kernel_folder()
    assert folder.parent == kernel_cache.cache_root() / "kernels"
    env = kernel_cache.environment()
    for part in ("python", "numba", "llvmlite", "numpy", "cpu", "cpu_features", "rbenvs_source"):
        assert env[part]


def _adder(c):
    def add(x):
        return x + c

    return add


def _scaled(f, k):
    def g(x):
        return k * f(x)

    return g


def test_the_fingerprint_follows_closures_constants_and_called_functions():
    fp = kernel_cache.fingerprint
    assert fp(_adder(1.0)) == fp(_adder(1.0))
    assert fp(_adder(1.0)) != fp(_adder(1.0000000000000002))  # one ulp: floats by their bits
    assert fp(_adder(1.0)) != fp(_adder(1))  # int and float compile differently
    assert fp(_scaled(_adder(1.0), 2.0)) != fp(
        _scaled(_adder(3.0), 2.0)
    )  # a value two closures down
    assert fp(_adder((1.0, 2.0))) != fp(_adder((1.0, 2.5)))
    assert fp(_adder(np.array([1.0, 2.0]))) != fp(_adder(np.array([1.0, 2.5])))

    from rbenvs.codegen import generate

    one = generate("def f(x):\n    return x + 1.0\n", "fingerprint test")["f"]
    two = generate("def f(x):\n    return x + 2.0\n", "fingerprint test")["f"]
    again = generate("def f(x):\n    return x + 1.0\n", "fingerprint test")["f"]
    assert fp(one) == fp(again) != fp(two)  # generated sources by their code, not their name
    # a global the code names, through the generated namespace
    g1 = generate("def f(x):\n    return h(x)\n", "fingerprint test", {"h": _adder(1.0)})["f"]
    g2 = generate("def f(x):\n    return h(x)\n", "fingerprint test", {"h": _adder(2.0)})["f"]
    assert fp(g1) != fp(g2)


def test_cache_info_and_clear(tmp_path, monkeypatch):
    run(tmp_path)
    monkeypatch.setenv(kernel_cache.CACHE_VARIABLE, str(tmp_path))
    stale = tmp_path / "kernels" / "cpython-3.0.0-old"
    stale.mkdir()
    (stale / "x.nbk").write_bytes(b"old")
    info = kernel_cache.info()
    names = {f["name"]: f for f in info["folders"]}
    assert (
        info["current"] in names
        and names[info["current"]]["files"] >= 1
        and names["cpython-3.0.0-old"]["files"] == 1
    )
    assert kernel_cache.clear(stale_only=True) == 1
    assert [f["name"] for f in kernel_cache.info()["folders"]] == [info["current"]]
    assert kernel_cache.clear() == names[info["current"]]["files"]
    assert kernel_cache.info()["folders"] == []


def test_the_modules_left_out_of_the_source_hash_hold_no_compiled_code(tmp_path):
    """An edit of a module in NOT_COMPILED keeps the kernels: none of them may hold code a kernel
    runs (a jitable function, a compiled form, a generated source or an njit of its own)."""
    import ast
    from pathlib import Path

    package = Path(kernel_cache.__file__).resolve().parent
    compiling = {"jitable", "compiled_form", "scalar_form", "njit", "generate", "elementwise"}
    left_out = [
        p
        for p in sorted(package.rglob("*.py"))
        if p.relative_to(package).parts[0] in kernel_cache.NOT_COMPILED
    ]
    assert len(left_out) >= len(kernel_cache.NOT_COMPILED)
    for path in left_out:
        for node in ast.walk(ast.parse(path.read_text())):
            name = (
                node.id
                if isinstance(node, ast.Name)
                else node.attr
                if isinstance(node, ast.Attribute)
                else None
            )
            assert name not in compiling, (
                f"{path.relative_to(package)}:{node.lineno} uses {name}: it is not NOT_COMPILED"
            )
    # an edit of one keeps the environment's key, an edit elsewhere changes it (on a copy)
    import shutil

    copy = tmp_path / "rbenvs"
    shutil.copytree(package, copy, ignore=shutil.ignore_patterns("__pycache__"))
    before = kernel_cache._hash_sources(copy)
    assert before == kernel_cache._source_hash()
    (copy / "headline.py").write_text((copy / "headline.py").read_text() + "\n# an edit\n")
    assert kernel_cache._hash_sources(copy) == before
    (copy / "rotations.py").write_text((copy / "rotations.py").read_text() + "\n# an edit\n")
    assert kernel_cache._hash_sources(copy) != before
