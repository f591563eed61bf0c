"""The type stub `python/quadtex/__init__.pyi` matches the module, and every public callable
documents its parameters."""

import ast
import inspect
import os
import pathlib
import subprocess
import sys

import pytest

import quadtex

STUB = pathlib.Path(__file__).resolve().parents[1] / "python" / "quadtex" / "__init__.pyi"


def _stub_tree():
    return ast.parse(STUB.read_text(encoding="utf-8"))


def _stub_all(tree):
    for node in tree.body:
        if isinstance(node, ast.Assign) and any(
            isinstance(t, ast.Name) and t.id == "__all__" for t in node.targets
        ):
            return ast.literal_eval(node.value)
    raise AssertionError("the stub has no __all__")


def _stub_functions(tree):
    """{"pack": FunctionDef, "Texture.filter": FunctionDef, …}"""
    out = {}
    for node in tree.body:
        if isinstance(node, ast.FunctionDef):
            out[node.name] = node
        elif isinstance(node, ast.ClassDef):
            for item in node.body:
                if isinstance(item, ast.FunctionDef):
                    out[f"{node.name}.{item.name}"] = item
    return out


def _runtime_callables():
    """{"pack": function, "Texture.filter": method, …}: every public one."""
    out = {}
    for name in quadtex.__all__:
        obj = getattr(quadtex, name)
        if name.startswith("_"):
            continue
        if inspect.isclass(obj):
            for attr, member in vars(obj).items():
                if not attr.startswith("_") and callable(member):
                    out[f"{name}.{attr}"] = getattr(obj, attr)
        elif callable(obj):
            out[name] = obj
    return out


def test_stub_all_is_the_module_all():
    assert _stub_all(_stub_tree()) == quadtex.__all__
    # Every public name (but the extension submodule) is in __all__.
    public = {
        n for n in dir(quadtex) if not n.startswith("_") and not inspect.ismodule(getattr(quadtex, n))
    }
    assert public <= set(quadtex.__all__)


def test_stub_signatures_match_the_runtime():
    stub = _stub_functions(_stub_tree())
    runtime = _runtime_callables()
    assert set(runtime) <= set(stub), f"missing from the stub: {sorted(set(runtime) - set(stub))}"
    for name, obj in runtime.items():
        sig = inspect.signature(obj)
        want = [(p.name, p.default) for p in sig.parameters.values() if p.name != "self"]
        node = stub[name]
        args = [a for a in node.args.args if a.arg != "self"]
        defaults = [None] * (len(args) - len(node.args.defaults)) + node.args.defaults
        got = [
            (a.arg, inspect.Parameter.empty if d is None else ast.literal_eval(d))
            for a, d in zip(args, defaults)
        ]
        assert got == want, f"{name}: stub {got} != runtime {want}"


def test_stubtest_agrees(tmp_path):
    """mypy's stubtest on the source stub (not the installed copy)."""
    pytest.importorskip("mypy.stubtest")
    allow = tmp_path / "allowlist.txt"
    # maturin installs the extension as the submodule quadtex.quadtex,
    # re-exported by the package; the stub describes the package.
    allow.write_text("quadtex\\.quadtex\n")
    env = dict(os.environ, MYPYPATH=str(STUB.parent.parent))
    run = subprocess.run(
        [sys.executable, "-m", "mypy.stubtest", "quadtex", "--allowlist", str(allow)],
        cwd=tmp_path,
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert run.returncode == 0, run.stdout + run.stderr


def test_every_public_callable_documents_its_parameters():
    for name, obj in _runtime_callables().items():
        doc = inspect.getdoc(obj) or ""
        assert doc.strip(), f"{name} has no docstring"
        sig = inspect.signature(obj)
        for p in sig.parameters.values():
            if p.name != "self":
                assert p.name in doc, f"{name}'s docstring does not mention {p.name}"
        if name in ("pack", "pack_tiles", "open", "Texture.filter", "Texture.integrate", "Texture.save"):
            assert "Returns" in doc and "Raises" in doc, f"{name}: {doc}"


def test_pack_docstring_names_every_file_type():
    doc = quadtex.pack.__doc__
    for kind in ("PNG", "JPEG", "OpenEXR", ".hdr", "SVG", "pack_tiles"):
        assert kind in doc, kind
    assert "memory_limit" in doc


def test_properties_are_documented():
    for name, member in vars(quadtex.Texture).items():
        if not name.startswith("_") and not callable(member):
            assert (member.__doc__ or "").strip(), name
