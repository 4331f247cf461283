"""Errors from Python read exactly as the CLI's."""
import numpy as np
import pytest

import skelflow


def cli_message(result):
    assert result.returncode == 2, result.stdout + result.stderr
    assert result.stderr.startswith("skelflow: ")
    return result.stderr[len("skelflow: "):].rstrip("\n")


def test_bad_parameter_in_a_file_reads_as_the_cli(data_dir, cli):
    pipeline = str(data_dir / "bad_param.yaml")
    expected = cli_message(cli("run", pipeline, "--quiet"))
    assert "node 'skeleton': param 'variant': 'smoth' is not one of" in expected
    with pytest.raises(skelflow.InputError) as e:
        skelflow.run(pipeline)
    assert str(e.value) == expected
    assert isinstance(e.value, skelflow.Error)


def test_bad_set_value_reads_as_the_cli(data_dir, cli):
    pipeline = str(data_dir / "small_vessel.yaml")
    expected = cli_message(cli("run", pipeline, "--quiet", "--set", "skeleton.end_point_length=-3"))
    assert expected.startswith(pipeline + ":") or "--set skeleton.end_point_length=-3" in expected
    with pytest.raises(skelflow.InputError) as e:
        skelflow.run(pipeline, set={"skeleton.end_point_length": -3})
    assert str(e.value) == expected
    expected = cli_message(cli("run", pipeline, "--quiet", "--set", "skeletn.variant=smooth"))
    with pytest.raises(skelflow.InputError) as e:
        skelflow.run(pipeline, set={"skeletn.variant": "smooth"})
    assert str(e.value) == expected and "did you mean 'skeleton'" in expected


def test_module_function_errors_are_the_cli_messages_of_the_same_node(tmp_path, cli):
    # The CLI's message for node 'doht' in a file, without the file position, is the function's.
    y = tmp_path / "p.yaml"
    y.write_text("skelflow: 1\nnodes:\n"
                 "  phantom: {module: synthetic.vessel_tree, params: {size: [16, 16, 16]}}\n"
                 "  dist: {module: distance.euclidean, inputs: {mask: phantom.mask}}\n"
                 "  doht: {module: thinning.doht, inputs: {mask: phantom.mask, priority: dist.distance}, "
                 "params: {variant: smoth, end_pont_length: 2}}\n")
    expected = cli_message(cli("validate", y)).splitlines()
    prefix = f"{y}:5:"
    assert all(line.startswith(prefix) for line in expected), expected
    expected = [line.split(": ", 1)[1] for line in expected]  # drop "file:line:col: "
    mask = np.zeros((16, 16, 16), np.uint8)
    mask[4:12, 4:12, 4:12] = 1
    dist = skelflow.modules.distance.euclidean(mask)
    with pytest.raises(skelflow.InputError) as e:
        skelflow.modules.thinning.doht(mask=mask, priority=dist, variant="smoth", end_pont_length=2)
    assert str(e.value).splitlines() == expected
    assert "did you mean 'end_point_length'" in str(e.value)


def test_wrong_voxel_type_and_missing_input_name_the_port():
    with pytest.raises(skelflow.InputError, match="^node 'doht': input 'mask': type mismatch: .* gives volume.f32, but 'mask' takes volume.u8$"):
        skelflow.modules.thinning.doht(mask=np.zeros((4, 4, 4), np.float32), priority=np.zeros((4, 4, 4), np.float32))
    with pytest.raises(skelflow.InputError, match="mask"):
        skelflow.modules.thinning.doht(priority=np.zeros((4, 4, 4), np.float32))
    with pytest.raises(skelflow.InputError, match="unknown parameter|cannot use a value"):
        skelflow.modules.thinning.doht(mask=np.zeros((4, 4, 4), np.uint8), variant={"a": 1})
