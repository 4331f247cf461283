"""Volumes cross between NumPy and Skelflow without copies, for every voxel type."""
import gc

import numpy as np
import pytest

import skelflow
from skelflow import _skelflow as core

VOXEL_TYPES = [np.uint8, np.uint16, np.uint32, np.uint64, np.int32, np.float32, np.float64]


def base_chain(a):
    while a is not None:
        yield a
        a = getattr(a, "base", None)


@pytest.mark.parametrize("dtype", VOXEL_TYPES)
def test_round_trip_of_every_voxel_type_shares_memory(dtype):
    a = (np.arange(5 * 4 * 3) % 7).astype(dtype).reshape(5, 4, 3)
    d = skelflow._to_data(skelflow.Volume(a, spacing=(3.0, 2.0, 1.0), origin=(0.5, 0.25, 0.0)), "test")
    assert core.wraps_array(d)  # the volume reads the array's memory, it did not copy it
    assert d.type_id == "volume." + {"uint8": "u8", "uint16": "u16", "uint32": "u32", "uint64": "u64",
                                     "int32": "i32", "float32": "f32", "float64": "f64"}[np.dtype(dtype).name]
    # Skelflow reports (x, y, z): nx = 3, ny = 4, nz = 5, spacing 1 2 3.
    assert "3x4x5" in d.describe() and "spacing 1 2 3" in d.describe()
    back = skelflow._from_data(d)
    assert isinstance(back, skelflow.Volume)
    assert back.dtype == dtype and back.shape == a.shape
    assert np.shares_memory(back, a)
    assert back.spacing == (3.0, 2.0, 1.0) and back.origin == (0.5, 0.25, 0.0)
    np.testing.assert_array_equal(back, a)


@pytest.mark.parametrize("dtype", VOXEL_TYPES)
def test_round_trip_through_a_pipeline_run(dtype, data_dir):
    # The given volume is the output of the replaced node; the run hands back the same memory.
    a = np.ones((6, 5, 4), dtype=dtype)
    out = skelflow.run(data_dir / "read_threshold.yaml", inputs={"read.volume": a}, targets=["seg"], threads=1)
    assert np.shares_memory(out["read.volume"], a)
    assert out["seg.mask"].shape == a.shape


def test_outputs_own_the_volume_without_copy():
    mask = np.zeros((20, 20, 20), np.uint8)
    mask[5:15, 5:15, 5:15] = 1
    dist = skelflow.modules.distance.euclidean(mask=mask)
    assert isinstance(dist, skelflow.Volume) and dist.dtype == np.float32
    # The array is a view of the framework's volume: its base is the capsule holding the volume.
    owners = list(base_chain(dist))
    assert any(type(o).__name__ == "PyCapsule" for o in owners)
    assert dist.flags.c_contiguous and not dist.flags.owndata
    # The data outlives everything but the array itself.
    view = dist[10]
    del dist, owners
    gc.collect()
    assert view[10, 10] == pytest.approx(5.0)
    assert view[0, 0] == 0.0


def test_volumes_pickle_with_their_geometry():
    import pickle

    v = skelflow.Volume(np.arange(8, dtype=np.float32).reshape(2, 2, 2), spacing=(3, 2, 1), origin=(1, 0, 0), unit="mm")
    w = pickle.loads(pickle.dumps(v))
    assert isinstance(w, skelflow.Volume) and w.spacing == (3.0, 2.0, 1.0) and w.origin == (1.0, 0.0, 0.0)
    assert w.unit == "mm"
    np.testing.assert_array_equal(w, v)
    assert w[1].spacing == (3.0, 2.0, 1.0)  # views keep the attributes


def test_bool_arrays_are_read_as_uint8_without_copy():
    b = np.zeros((4, 4, 4), bool)
    b[1:3, 1:3, 1:3] = True
    d = skelflow._to_data(b, "test")
    assert d.type_id == "volume.u8"
    assert np.shares_memory(skelflow._from_data(d), b)


def test_non_contiguous_arrays_are_copied_and_unsupported_dtypes_refused():
    a = np.zeros((4, 6, 8), np.float32)[:, ::2, :]
    d = skelflow._to_data(a, "test")
    assert not np.shares_memory(skelflow._from_data(d), a)
    with pytest.raises(skelflow.InputError, match="dtype int16"):
        skelflow._to_data(np.zeros((2, 2, 2), np.int16), "test")
    with pytest.raises(skelflow.InputError, match="3-dimensional"):
        skelflow._to_data(np.zeros((2, 2), np.uint8), "test")


def test_input_array_stays_alive_while_skelflow_holds_it():
    d = skelflow._to_data(np.full((3, 3, 3), 7, np.uint16), "test")  # no Python reference to the array left
    gc.collect()
    back = skelflow._from_data(d)
    assert int(back.sum()) == 7 * 27


def test_tables_are_dicts_of_arrays():
    t = skelflow.Table({"id": np.arange(3), "length": np.array([1.5, 2.0, 3.25]), "name": ["a", "b", "c"]},
                       units={"length": "µm"})
    back = skelflow._from_data(skelflow._to_data(t, "test"))
    assert list(back) == ["id", "length", "name"]
    assert back["id"].dtype == np.int64 and back["length"].dtype == np.float64
    assert back["name"] == ["a", "b", "c"] and back.units["length"] == "µm"
    df = back.to_pandas()
    assert list(df.columns) == ["id", "length", "name"] and df["length"].sum() == pytest.approx(6.75)
    assert df.attrs["units"]["length"] == "µm"


def test_the_unit_travels_through_a_module():
    # The grid of a volume carries its unit: a mask in mm gives a distance map in mm.
    mask = np.zeros((12, 12, 12), np.uint8)
    mask[2:10, 2:10, 2:10] = 1
    dist = skelflow.modules.distance.euclidean(mask=skelflow.Volume(mask, spacing=(0.5, 0.5, 0.5), unit="mm"))
    assert dist.unit == "mm" and dist.spacing == (0.5, 0.5, 0.5)
