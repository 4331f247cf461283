"""Every module is a function generated from its spec; Ctrl+C cancels a run."""
import inspect
import os
import pathlib
import signal
import subprocess
import sys
import textwrap
import time

import numpy as np
import pytest

import skelflow


def test_every_module_is_a_function_with_its_spec_as_docstring(cli):
    listed = [line.split()[0] for line in cli("modules").stdout.splitlines() if line.strip()]
    assert listed and listed == skelflow.module_names()
    for name in listed:
        family, short = name.split(".", 1)
        f = getattr(getattr(skelflow.modules, family), short)
        assert f.spec["name"] == name
        assert f.__doc__.startswith(f.spec["doc"])
        sig = inspect.signature(f)
        for p in f.spec["inputs"]:
            assert p["name"] in sig.parameters and p["doc"] in f.__doc__
        for p in f.spec["params"]:
            assert f"    {p['name']} (" in f.__doc__ and p["doc"] in f.__doc__


def test_doht_docstring_lists_types_defaults_and_choices():
    doc = skelflow.modules.thinning.doht.__doc__
    sig = inspect.signature(skelflow.modules.thinning.doht)
    assert list(sig.parameters)[:2] == ["mask", "priority"]
    variant = next(p for p in skelflow.modules.thinning.doht.spec["params"] if p["name"] == "variant")
    assert sig.parameters["variant"].default == variant["default"]
    line = next(l for l in doc.splitlines() if l.startswith("    variant ("))
    assert "choice" in line and all(repr(c) in line for c in variant["choices"])
    assert "Returns skelflow.Outputs" in doc and "    skeleton (volume.u8)" in doc
    from skelflow.modules import thinning  # the families import as modules too
    assert thinning.doht is skelflow.modules.thinning.doht


def test_module_function_equals_the_pipeline_node(data_dir):
    out = skelflow.run(data_dir / "small_vessel.yaml", targets=["skeleton"], threads=2)
    mask, dist = out["largest.mask"], out["distance.distance"]
    skel = skelflow.modules.thinning.doht(mask, dist, variant="smooth", end_point_length=2, threads=2).skeleton
    np.testing.assert_array_equal(skel, out["skeleton.skeleton"])
    assert skel.dtype == np.uint8 and skel.sum() > 0
    # The call's run report, as `skelflow run --report` writes it: the one node that ran is doht.
    report = skelflow.last_report()
    assert report["ok"] is True
    assert [n["id"] for n in report["nodes"] if n["module"] == "thinning.doht"] == ["doht"]
    assert all(n["seconds"] >= 0 for n in report["nodes"])


def test_module_function_writes_files_like_a_node(tmp_path):
    v = skelflow.Volume(np.arange(24, dtype=np.uint16).reshape(2, 3, 4), spacing=(3, 2, 1))
    assert skelflow.modules.io.write_volume(v, path="v.h5", output_dir=tmp_path) is None
    back = skelflow.modules.io.read_volume(path=str(tmp_path / "v.h5"))
    np.testing.assert_array_equal(back, v)
    assert back.spacing == (3.0, 2.0, 1.0)


def test_the_gil_is_released_while_a_module_runs():
    import threading

    phantom = skelflow.modules.synthetic.vessel_tree(size=[128, 128, 128], seed=2, roots=4)
    counts, done = [0], threading.Event()

    def count():
        while not done.is_set():
            counts[0] += 1

    worker = threading.Thread(target=count)
    worker.start()
    try:
        time.sleep(0.05)
        before = counts[0]
        t = time.monotonic()
        skelflow.modules.distance.euclidean(phantom.mask, threads=1)
        elapsed = time.monotonic() - t
        during = counts[0] - before
    finally:
        done.set()
        worker.join()
    # With the GIL held for the whole call the counting thread could not run at all.
    assert elapsed > 0 and during > 1000, (during, elapsed)


CHILD = textwrap.dedent("""
    import sys, time, skelflow
    p = skelflow.Pipeline()
    p.add_node("phantom", "synthetic.vessel_tree", size=[448, 448, 448], seed=1, roots=6)
    p.add_node("smooth", "segmentation.gaussian", sigma=[2.0, 2.0, 2.0])
    p.add_node("dist", "distance.euclidean")
    p.add_node("skel", "thinning.doht")
    p.add_node("save", "io.write_volume", path="out/skeleton.h5")
    p.connect("phantom.image", "smooth.image")
    p.connect("phantom.mask", "dist.mask")
    p.connect("phantom.mask", "skel.mask")
    p.connect("dist.distance", "skel.priority")
    p.connect("skel.skeleton", "save.volume")
    t = time.monotonic()
    try:
        print("started", flush=True)
        p.run(threads=1, output_dir=sys.argv[1])
        print("finished", flush=True)
    except KeyboardInterrupt:
        print("interrupted after %.1f s" % (time.monotonic() - t), flush=True)
""")


def test_ctrl_c_cancels_a_run_and_leaves_no_output(tmp_path):
    env = dict(os.environ)
    proc = subprocess.Popen([sys.executable, "-c", CHILD, str(tmp_path)], stdout=subprocess.PIPE, text=True, env=env)
    assert proc.stdout.readline().strip() == "started"
    # The run takes ~3 s on an idle 2-core machine (single-threaded); interrupt it early. (At 320³
    # and 1.5 s it could finish first on an idle machine.)
    time.sleep(0.5)
    t = time.monotonic()
    proc.send_signal(signal.SIGINT)
    out, _ = proc.communicate(timeout=120)
    assert proc.returncode == 0, out
    assert out.startswith("interrupted"), out
    assert time.monotonic() - t < 30  # the run stopped, it did not finish first
    assert not any(pathlib.Path(tmp_path).rglob("*")), list(pathlib.Path(tmp_path).rglob("*"))


CHILD_MODULE = textwrap.dedent("""
    import time, skelflow
    t = time.monotonic()
    try:
        print("started", flush=True)
        skelflow.modules.synthetic.network(shape="rods", size=[640, 640, 640], sigma=2.0, threads=1)
        print("finished", flush=True)
    except KeyboardInterrupt:
        print("interrupted after %.1f s" % (time.monotonic() - t), flush=True)
""")


def test_ctrl_c_cancels_a_module_function():
    proc = subprocess.Popen([sys.executable, "-c", CHILD_MODULE], stdout=subprocess.PIPE, text=True)
    assert proc.stdout.readline().strip() == "started"
    time.sleep(0.5)  # the module takes ~2.3 s on an idle machine
    t = time.monotonic()
    proc.send_signal(signal.SIGINT)
    out, _ = proc.communicate(timeout=120)
    assert proc.returncode == 0 and out.startswith("interrupted"), out
    assert time.monotonic() - t < 30
