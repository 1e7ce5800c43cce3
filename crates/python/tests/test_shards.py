"""Sharded renders from Python: merging n shards (n = 1, 2, 3, 7, rendered on 1 to 3 threads,
merged in reverse order) is bitwise the single run for the covariance, intensity, fields and
wave; shards pickle and save; a missing shard is named by index and rendering it completes the
merge; the command line merges Python's shard files and Python merges the command line's.
Run time: a few seconds."""

import pickle
import subprocess

import numpy as np
import pytest

import speckle
from conftest import TINY, WAVE

RENDERS = {
    "covariance": speckle.covariance,
    "intensity": speckle.intensity,
    "fields": speckle.fields,
    "wave": speckle.wave,
}


def assert_same(a: speckle.Result, b: speckle.Result) -> None:
    assert type(a) is type(b)
    xa, xb = a.arrays(), b.arrays()
    assert xa.keys() == xb.keys()
    for k in xa:
        assert xa[k].dtype == xb[k].dtype and xa[k].shape == xb[k].shape, k
        assert xa[k].tobytes() == xb[k].tobytes(), f"{k} differs"


@pytest.mark.parametrize("kind", list(RENDERS))
def test_merged_shards_are_bitwise_the_single_run(kind):
    render = RENDERS[kind]
    scene = speckle.load(WAVE if kind == "wave" else TINY)
    whole = render(scene, threads=1)
    for n in [1, 2, 3, 7]:
        shards = [render(scene, shard=(i, n), threads=1 + i % 3) for i in range(n)]
        assert all(isinstance(s, speckle.Shard) for s in shards)
        assert [s.index for s in shards] == list(range(n)) and shards[0].count == n
        merged = speckle.merge(reversed(shards))
        assert_same(merged, whole)


def test_shards_pickle_save_and_read(tmp_path):
    scene = speckle.load(TINY)
    shards = [speckle.covariance(scene, shard=f"{i}/3") for i in range(3)]
    s = shards[1]
    assert s.kind == "covariance" and s.units == (42, 84) and s.total_units == 127
    assert s.file_name == "tiny.cov.1-of-3.shard" and len(s.run_hash) == 16
    copies = [pickle.loads(pickle.dumps(x)) for x in shards]
    assert [c.to_bytes() for c in copies] == [x.to_bytes() for x in shards]
    paths = [speckle.save_shard(x, tmp_path / "shards") for x in shards]
    assert speckle.read_shard(paths[0]).to_bytes() == shards[0].to_bytes()
    whole = speckle.covariance(scene)
    assert_same(speckle.merge(paths), whole)
    assert_same(speckle.merge([paths[0], copies[1], shards[2]]), whole)
    assert sorted(p.name for p in (tmp_path / "shards").iterdir()) == [
        f"tiny.cov.{i}-of-3.shard" for i in range(3)
    ]


def test_a_missing_shard_is_named_by_index():
    scene = speckle.load(WAVE)
    shards = {i: speckle.wave(scene, shard=(i, 7)) for i in [0, 1, 2, 4, 6]}
    with pytest.raises(speckle.ShardError) as e:
        speckle.merge(shards.values())
    assert isinstance(e.value, ValueError)
    assert e.value.missing == [3, 5] and e.value.count == 7
    assert str(e.value).startswith("shards 3/7, 5/7 are missing"), str(e.value)
    for i in e.value.missing:
        shards[i] = speckle.wave(scene, shard=(i, 7))
    assert_same(speckle.merge(shards.values()), speckle.wave(scene))


def test_shards_of_other_runs_are_refused():
    a = speckle.covariance(TINY, shard=(0, 2))
    with pytest.raises(speckle.ShardError, match=r"different seeds \(6 and 5\)"):
        speckle.merge([a, speckle.covariance(TINY, seed=6, shard=(1, 2))])
    with pytest.raises(speckle.ShardError, match="different renders"):
        speckle.merge([a, speckle.intensity(TINY, shard=(1, 2))])
    with pytest.raises(speckle.ShardError, match="overlap"):
        speckle.merge([a, a])
    with pytest.raises(speckle.ShardError, match="not a speckle shard file"):
        speckle.Shard.from_bytes(b"nothing of the kind")
    with pytest.raises(speckle.ShardError, match="shard"):
        speckle.covariance(TINY, shard=(2, 2))


def test_the_command_line_and_python_merge_each_others_shards(speckle_bin, tiny_file, tmp_path):
    shards = tmp_path / "shards"
    for i in (0, 2):
        r = subprocess.run(
            [str(speckle_bin), "covariance", str(tiny_file), "--shard", f"{i}/3",
             "--out", str(shards), "-q"],
            capture_output=True, text=True,
        )
        assert r.returncode == 0, r.stderr
    speckle.save_shard(speckle.covariance(tiny_file, shard=(1, 3)), shards)
    files = sorted(shards.glob("*.shard"))
    assert len(files) == 3
    merged = speckle.merge(files)
    out = tmp_path / "merged"
    r = subprocess.run(
        [str(speckle_bin), "merge", *map(str, files), "--out", str(out), "--no-png"],
        capture_output=True, text=True,
    )
    assert r.returncode == 0, r.stderr
    assert np.load(out / "tiny.cov.npy").tobytes() == merged.cov.tobytes()
    assert np.load(out / "tiny.cov_stderr.npy").tobytes() == merged.cov_stderr.tobytes()
    # A missing shard: the command line names it and exits with 2.
    r = subprocess.run(
        [str(speckle_bin), "merge", str(files[0]), str(files[2]), "--out", str(out)],
        capture_output=True, text=True,
    )
    assert r.returncode == 2 and "shard 1/3 is missing" in r.stderr, r.stderr
