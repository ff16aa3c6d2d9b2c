"""Damaged, truncated, foreign and inconsistent model bundles are refused with one clear line:
nothing loads silently wrong (a flipped byte in a weight is caught by the bundle's checksum)."""
import zipfile

import pytest
import torch

from engine.models.bundle import BundleError, load_bundle, untrained_bundle


@pytest.fixture(scope="module")
def saved(tmp_path_factory):
    path = tmp_path_factory.mktemp("bundle") / "model.pt"
    untrained_bundle().save(path)
    return path


def refused(path) -> str:
    with pytest.raises(BundleError) as info:
        load_bundle(path)
    message = str(info.value)
    assert "\n" not in message and str(path) in message
    return message


def test_a_saved_bundle_loads(saved):
    assert load_bundle(saved).parts


def test_empty_and_truncated_files_are_refused(saved, tmp_path):
    empty = tmp_path / "empty.pt"
    empty.write_bytes(b"")
    assert "not a readable model bundle" in refused(empty)
    truncated = tmp_path / "truncated.pt"
    truncated.write_bytes(saved.read_bytes()[: saved.stat().st_size // 2])
    assert "not a readable model bundle" in refused(truncated)


def test_a_flipped_byte_inside_a_weight_is_caught(saved, tmp_path):
    damaged = tmp_path / "damaged.pt"
    data = bytearray(saved.read_bytes())
    with zipfile.ZipFile(saved) as archive:
        entry = max(archive.infolist(), key=lambda i: i.file_size)    # the largest tensor's bytes
    start = entry.header_offset + 30 + len(entry.filename.encode()) + len(entry.extra)
    data[start + entry.file_size // 2] ^= 0x40
    damaged.write_bytes(bytes(data))
    assert "checksum" in refused(damaged) or "not a readable" in refused(damaged)


@pytest.mark.parametrize("change, why", [
    ({"version": "2"}, "bundle version"), ({"version": 99}, "bundle version"), ({"format": "other"}, "not a Sketch2Colab"),
    ({"weights": [1, 2]}, "damaged"), ({"metadata": "x"}, "damaged")])
def test_foreign_or_inconsistent_contents_are_refused(saved, tmp_path, change, why):
    data = torch.load(saved, weights_only=True)
    data.update(change)
    path = tmp_path / "changed.pt"
    torch.save(data, path)
    assert why in refused(path)


def test_marked_trained_without_weights_is_refused(saved, tmp_path):
    data = torch.load(saved, weights_only=True)
    data["metadata"]["trained"] = True
    del data["weights"]["student"]
    data.pop("weights_sha256")
    path = tmp_path / "hollow.pt"
    torch.save(data, path)
    assert "marked trained but has no weights for student" in refused(path)
