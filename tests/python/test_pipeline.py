"""skelflow.run and skelflow.Pipeline: the same executor, files and YAML as the CLI."""
import filecmp
import pathlib

import numpy as np
import pytest

import skelflow

OUTPUT_FILES = ["skeleton.h5", "network.am", "network.vtp", "segments.csv", "summary.csv"]


def test_run_from_python_equals_cli_byte_for_byte(data_dir, tmp_path, cli):
    pipeline = data_dir / "small_vessel.yaml"
    r = cli("run", pipeline, "--quiet", "--threads", "2", "--set", "phantom.seed=7", "--output-dir", tmp_path / "cli")
    assert r.returncode == 0, r.stderr
    outputs = skelflow.run(pipeline, set={"phantom.seed": 7}, threads=2, output_dir=tmp_path / "py")
    for name in OUTPUT_FILES:
        a, b = tmp_path / "cli" / "out" / name, tmp_path / "py" / "out" / name
        assert a.stat().st_size > 0
        assert filecmp.cmp(a, b, shallow=False), f"{name} differs between the CLI and Python runs"
    # The outputs come back as Python objects.
    assert isinstance(outputs["skeleton.skeleton"], skelflow.Volume)
    assert outputs["skeleton.skeleton"].shape == (40, 48, 48)
    assert isinstance(outputs["graph.graph"], skelflow.Graph)
    assert isinstance(outputs["stats.summary"], skelflow.Table)
    # Another seed gives another skeleton: `set` reached the phantom.
    other = skelflow.run(pipeline, set={"phantom.seed": 8}, threads=2, outputs=["skeleton.skeleton"])
    assert list(other) == ["skeleton.skeleton"]
    assert not np.array_equal(other["skeleton.skeleton"], outputs["skeleton.skeleton"])


def test_pipeline_built_in_code_saves_the_yaml_of_the_cli(data_dir, tmp_path, cli):
    p = skelflow.Pipeline()
    p.add_node("read", "io.read_volume", path="image.h5")
    p.add_node("seg", "segmentation.threshold", method="manual", low=0.5)
    p.add_node("save", "io.write_volume", path="out/mask.h5")
    p.connect("read.volume", "seg.image")
    p.connect("seg.mask", "save.volume")
    loaded = skelflow.Pipeline.load(data_dir / "read_threshold.yaml")
    assert p == loaded
    assert p.to_yaml() == loaded.to_yaml()
    saved = tmp_path / "built.yaml"
    p.save(saved)
    assert skelflow.Pipeline.load(saved) == loaded
    r = cli("validate", saved)  # the CLI reads what Python wrote; only the missing input file is wrong
    assert r.returncode == 2 and "image.h5" in r.stderr, r.stderr


def test_connect_refuses_what_the_gui_refuses():
    p = skelflow.Pipeline()
    p.add_node("phantom", "synthetic.vessel_tree")
    p.add_node("dist", "distance.euclidean")
    with pytest.raises(skelflow.InputError, match="phantom.nope"):
        p.connect("phantom.nope", "dist.mask")
    with pytest.raises(skelflow.InputError, match="unknown module 'thinning.dohtt' \\(did you mean 'thinning.doht'\\?\\)"):
        p.add_node("t", "thinning.dohtt")


def test_inputs_replace_a_node_with_a_numpy_volume(data_dir, tmp_path, cli):
    rng = np.random.default_rng(5)
    image = rng.random((12, 10, 8)).astype(np.float32)
    vol = skelflow.Volume(image, spacing=(2.0, 1.0, 0.5))
    out = skelflow.run(data_dir / "read_threshold.yaml", inputs={"read.volume": vol}, threads=1,
                       output_dir=tmp_path / "py")
    mask = out["seg.mask"]
    np.testing.assert_array_equal(mask, (image >= 0.5).astype(mask.dtype))
    assert mask.spacing == (2.0, 1.0, 0.5)
    # The given volume is what the replaced node outputs: the very same memory comes back.
    assert np.shares_memory(out["read.volume"], image)
    assert (tmp_path / "py" / "out" / "mask.h5").exists()
    # The file the reader would have read never existed: the node really was replaced.
    assert not (data_dir / "image.h5").exists()
    # The CLI reads the file Python wrote (a mask of the same shape).
    r = cli("info", tmp_path / "py" / "out" / "mask.h5")
    assert r.returncode == 0 and "8" in r.stdout, r.stdout + r.stderr


def test_inputs_name_nodes_and_ports_like_the_cli(data_dir):
    a = np.zeros((4, 4, 4), np.float32)
    with pytest.raises(skelflow.InputError, match="no node 'raed'.*did you mean 'read'"):
        skelflow.run(data_dir / "read_threshold.yaml", inputs={"raed.volume": a})
    with pytest.raises(skelflow.InputError, match="has no output 'volum'.*did you mean 'volume'.*its outputs: volume"):
        skelflow.run(data_dir / "read_threshold.yaml", inputs={"read.volum": a})


def test_failed_run_leaves_no_output(data_dir, tmp_path):
    # A float64 volume is given where the threshold accepts it, but the writer's folder is a file.
    (tmp_path / "out").write_text("a file where the output folder should be")
    with pytest.raises(skelflow.InputError, match="out"):
        skelflow.run(data_dir / "read_threshold.yaml", inputs={"read.volume": np.zeros((3, 3, 3))},
                     output_dir=tmp_path)
    assert (tmp_path / "out").read_text().startswith("a file")
