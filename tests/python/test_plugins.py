"""Plugins (docs/plugins.md) in Python: a plugin's modules become functions at import; a refused
plugin is a warning naming its file. Each case runs in a fresh interpreter (plugins load once, at
import), with SKELFLOW_PLUGIN_PATH set and no user folder."""
import json
import os
import pathlib
import subprocess
import sys
import textwrap

import pytest

PLUGINS = pathlib.Path(os.environ.get("SKELFLOW_TEST_PLUGINS", ""))


def python(code, plugin_path, tmp_path):
    if not (PLUGINS / "good").is_dir():
        pytest.fail("SKELFLOW_TEST_PLUGINS must name build/tests/plugins (ctest sets it)")
    env = dict(os.environ, SKELFLOW_PLUGIN_PATH=plugin_path, XDG_DATA_HOME=str(tmp_path / "xdg"))
    r = subprocess.run([sys.executable, "-W", "always", "-c", textwrap.dedent(code)], capture_output=True,
                       text=True, env=env)
    assert r.returncode == 0, r.stderr
    return r


def test_plugin_module_is_a_function_that_runs(tmp_path):
    r = python("""
        import json, numpy as np, skelflow
        f = skelflow.modules.plugin_test.invert
        zeros = f(mask=np.ones((2, 3, 4), np.uint8), value=7)  # one output: the volume itself
        sevens = f(mask=zeros, value=7)
        print(json.dumps({"plugins": skelflow.plugins(), "zeros": int(zeros.sum()), "sevens": sevens.tolist(),
                          "doc": f.__doc__, "names": skelflow.module_names()}))
        try:
            f(mask=zeros, value=300)
        except skelflow.InputError as e:
            print("ERROR", e)
        """, str(PLUGINS / "good"), tmp_path)
    lines = r.stdout.splitlines()
    out = json.loads(lines[0])
    assert out["plugins"] == [[str((PLUGINS / "good" / "invert_plugin.so").resolve()), ["plugin_test.invert"]]]
    assert out["zeros"] == 0
    assert out["sevens"] == [[[7] * 4] * 3] * 2
    assert "value of the voxels that were background" in out["doc"]
    assert "plugin_test.invert" in out["names"]
    assert "'value'" in lines[1] and "out of range [1, 255]" in lines[1], lines[1]
    assert r.stderr == ""


def test_refused_plugin_is_a_warning_naming_the_file(tmp_path):
    bad = PLUGINS / "bad" / "bad_abi_plugin.so"
    r = python("""
        import skelflow
        print(skelflow.plugins(), hasattr(skelflow.modules, "plugin_test"))
        """, str(bad), tmp_path)
    assert r.stdout.strip() == "[] False"
    assert "RuntimeWarning: skelflow: plugin " + str(bad.resolve()) + ": built for another Skelflow" in r.stderr
    assert "expected ABI tag: skelflow " in r.stderr and "found ABI tag:    skelflow 0.0.1" in r.stderr
