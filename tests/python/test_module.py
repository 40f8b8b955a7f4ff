"""`import residue` (app/python): arrays in and out, the same numbers as residue-cli to the last bit, core's errors
as residue.Error, a denoise cancelled from another thread. Run by ctest (python_module) with PYTHONPATH at the
module and RESIDUE_CLI at the command line tool."""
import json
import os
import subprocess
import threading

import numpy as np
import OpenImageIO as oiio
import pytest

import residue

CLI = os.environ["RESIDUE_CLI"]
ROOM = os.path.join(os.environ["RESIDUE_SOURCE"], "resources", "examples", "room")


def read_rgb(path):
    inp = oiio.ImageInput.open(path)
    pixels = inp.read_image(0, 0, 0, 3, "float")
    inp.close()
    return np.asarray(pixels, dtype=np.float32)


@pytest.fixture(scope="module")
def room():
    return residue.load(os.path.join(ROOM, "noisy.exr"))


def test_a_render_loads_with_its_aovs_and_reference(room):
    assert room.convention == "Blender Cycles"
    assert room.color.shape == (192, 192, 3) and room.color.dtype == np.float32
    assert room.albedo.shape == (192, 192, 3) and room.normal.shape == (192, 192, 3) and room.depth.shape == (192, 192, 1)
    assert room.reference is not None and any("reference" in n for n in room.notes)


def test_an_array_written_and_read_back_is_the_same(tmp_path):
    rng = np.random.default_rng(3)
    image = (np.exp(rng.normal(size=(17, 23, 3))) * 0.3).astype(np.float32)
    path = str(tmp_path / "x.exr")
    residue.write_exr(path, image, half=False)
    assert np.array_equal(residue.load(path).color, image)
    with pytest.raises(residue.Error, match="x.exr"):
        residue.write_exr(path, image)  # never replaced unless asked
    residue.write_exr(path, image * 2, half=False, overwrite=True)
    assert np.array_equal(read_rgb(path), image * 2)


def test_denoise_equals_the_cli_to_the_last_bit(room, tmp_path):
    out = residue.denoise(room, "multiscale")
    path = str(tmp_path / "cli.exr")
    subprocess.run([CLI, "denoise", os.path.join(ROOM, "noisy.exr"), "-m", "multiscale", "--float", "-o", path],
                   check=True, capture_output=True)
    assert np.array_equal(out, read_rgb(path))
    assert np.isfinite(out).all()


def test_metrics_and_flip_equal_the_clis(room):
    ev = json.loads(subprocess.run([CLI, "eval", "--json", os.path.join(ROOM, "noisy.exr")], check=True,
                                   capture_output=True, text=True).stdout)["rows"][0]
    m = residue.metrics(room.color, room.reference)
    for k in ("relmse", "mse", "psnr", "ssim", "pixels"):
        assert m[k] == ev[k], k
    f = residue.flip(room.color, room.reference)
    assert f["mean"] == ev["hdr_flip"]
    assert f["map"].shape == (192, 192, 1) and f["exposures"][2] >= 2


def test_progress_reaches_the_whole_work_and_false_stops(room):
    seen = []
    residue.denoise(room, "tiny", tile=64, progress=lambda done, total: seen.append((done, total)) or True)
    assert len(seen) == 9 and seen[-1][0] == seen[-1][1] > 0
    assert all(a[0] < b[0] for a, b in zip(seen, seen[1:]))
    with pytest.raises(residue.Cancelled):
        residue.denoise(room, "tiny", tile=64, progress=lambda done, total: False)


def test_each_tile_of_the_result_arrives_with_its_pixels(room):
    # tiny has no post-step that changes a tile afterwards once the energy correction and strength are off
    tiles = []
    out = residue.denoise(room, "tiny", tile=64, energy_correction=False,
                          on_tile=lambda rect, pixels: tiles.append((rect, pixels.copy())))
    assert len(tiles) == 9
    covered = np.zeros(out.shape[:2], dtype=int)
    for (x, y, w, h), pixels in tiles:
        assert pixels.shape == (h, w, 3)
        assert np.array_equal(pixels, out[y:y + h, x:x + w])
        covered[y:y + h, x:x + w] += 1
    assert (covered == 1).all()
    with pytest.raises(residue.Cancelled):
        residue.denoise(room, "tiny", tile=64, on_tile=lambda rect, pixels: False)


def test_a_denoise_is_cancelled_from_another_thread(room):
    token = residue.CancelToken()
    reached, cancelled = threading.Event(), threading.Event()
    outcome = {}

    def hold_at_first_tile(done, total):  # the run waits here until the main thread has cancelled it
        reached.set()
        cancelled.wait(60)
        return True

    def run():
        try:
            residue.denoise(room, "small", tile=64, progress=hold_at_first_tile, cancel=token)
            outcome["result"] = "finished"
        except residue.Cancelled:
            outcome["result"] = "cancelled"

    worker = threading.Thread(target=run)
    worker.start()
    assert reached.wait(60)
    token.cancel()
    cancelled.set()
    worker.join(60)
    assert outcome.get("result") == "cancelled" and token.cancelled


def test_errors_are_residue_errors_with_cores_message(room):
    with pytest.raises(residue.Error, match="no-such-render.exr"):
        residue.load("/no-such-render.exr")
    with pytest.raises(residue.Error, match="no model \"nosuchmodel\""):
        residue.denoise(room, "nosuchmodel")
    with pytest.raises(residue.Error, match="same size"):
        residue.metrics(np.zeros((4, 4, 3), np.float32), np.zeros((4, 5, 3), np.float32))


def test_a_region_only_changes_the_region(room):
    out = residue.denoise(room, "tiny", roi=(40, 30, 64, 50))
    inside = np.zeros(out.shape[:2], bool)
    inside[30:80, 40:104] = True
    assert np.array_equal(out[~inside], room.color[~inside])  # the noisy colour outside
    assert not np.array_equal(out[inside], room.color[inside])


def test_arrays_by_role_denoise_as_the_file_does(room):
    arrays = residue.stack(room.color, albedo=room.albedo, normal=room.normal, depth=room.depth,
                           reference=room.reference, normal_space="camera")
    assert arrays.convention == "arrays" and arrays.reference is not None
    assert np.array_equal(residue.denoise(arrays, "tiny"), residue.denoise(room, "tiny"))
    with pytest.raises(residue.Error, match="albedo is 4x4 but the colour is 192x192"):
        residue.stack(room.color, albedo=np.zeros((4, 4, 3), np.float32))


def test_pytorch_tensors_go_in_and_come_out_without_a_copy(room):
    torch = pytest.importorskip("torch")  # Debian's python3-torch (tools/setup.sh installs it)
    tensors = {role: torch.from_numpy(getattr(room, role)) for role in ("color", "albedo", "normal", "depth")}
    # A tensor is taken as the array it shares memory with (.numpy(): no copy), and so is the result.
    arrays = residue.stack(tensors["color"].numpy(), albedo=tensors["albedo"].numpy(),
                           normal=tensors["normal"].numpy(), depth=tensors["depth"].numpy(), normal_space="camera")
    out = residue.denoise(arrays, "tiny")
    result = torch.from_numpy(out)
    assert result.shape == (192, 192, 3) and result.dtype == torch.float32
    assert result.data_ptr() == out.ctypes.data, "the result is the array's memory, not a copy"
    assert torch.equal(result, torch.from_numpy(residue.denoise(room, "tiny")))
    # Metrics of tensors, as of their arrays; a tensor computed in torch goes in as well.
    doubled = (tensors["color"] * 2).numpy()
    assert residue.metrics(doubled, room.reference)["relmse"] == residue.metrics(room.color * 2, room.reference)["relmse"]


def test_denoise_to_exr_records_what_ran_as_the_cli_does(room, tmp_path):
    path = str(tmp_path / "out.exr")
    ran = residue.denoise_to_exr(room, path, "tiny", half=False)
    assert ran["model"] == "tiny" and ran["seconds"] > 0 and ran["backend"]
    spec = oiio.ImageInput.open(path).spec()
    assert spec.get_string_attribute("residue:model") == "tiny"
    assert spec.get_string_attribute("residue:written_by") == "residue (Python)"
    assert spec.get_string_attribute("residue:architecture") and spec.get_string_attribute("residue:backend")
    assert np.array_equal(read_rgb(path), residue.denoise(room, "tiny"))
    with pytest.raises(residue.Error, match="out.exr"):
        residue.denoise_to_exr(room, path, "tiny")  # refused before any work: the file is there


def test_maps_and_cards(room):
    rse = residue.error_map(room.color, room.reference, "rse")
    assert rse.shape == (192, 192, 1)
    assert np.isclose(rse.mean(dtype=np.float64), residue.metrics(room.color, room.reference)["relmse"], rtol=1e-6)
    with pytest.raises(residue.Error, match="expected abs, se, rse or ssim"):
        residue.error_map(room.color, room.reference, "psnr")
    cards = {c["family"]: c for c in residue.models()}
    assert {"multiscale", "best", "oidn", "bilateral"} <= set(cards)
    assert cards["best"]["alias_of"] == "multiscale" and cards["best"]["ensemble"] == 8
    assert cards["multiscale"]["gflop_per_mp"] > 0 and cards["multiscale"]["validation"]["scenes"] > 0


SHOT = os.path.join(os.environ["RESIDUE_SOURCE"], "tests", "data", "shot")


def test_frames_load_by_pattern_as_one_by_one():
    pattern = os.path.join(SHOT, "noisy.####.exr")
    every = residue.load_frames(pattern)
    on_disk = sorted(f for f in os.listdir(SHOT) if f.startswith("noisy."))
    assert len(every) == len(on_disk) >= 4
    some = residue.load_frames(pattern, "3,1-2", reference=os.path.join(SHOT, "reference.####.exr"))
    for stack, frame in zip(some, (3, 1, 2)):
        alone = residue.load(os.path.join(SHOT, f"noisy.{frame:04d}.exr"))
        assert np.array_equal(stack.color, alone.color) and np.array_equal(stack.motion, alone.motion)
        assert stack.reference is not None
    with pytest.raises(residue.Error, match="noisy.0999.exr"):
        residue.load_frames(pattern, "999")
    with pytest.raises(residue.Error, match="names no frame number"):
        residue.load_frames(os.path.join(SHOT, "noisy.exr"))


def test_a_frame_denoised_with_its_neighbours_equals_the_clis_temporal_run(tmp_path):
    frames = residue.load_frames(os.path.join(SHOT, "noisy.####.exr"), "1-4")
    pattern = str(tmp_path / "temporal.####.exr")
    subprocess.run([CLI, "denoise", os.path.join(SHOT, "noisy.####.exr"), "--frames", "1-3", "--temporal", "--float",
                    "-o", pattern], check=True, capture_output=True)
    for t in (0, 1, 2):  # frame 1 has no frame before it; the CLI reads frame 4 beside frame 3, outside its range
        out, missing = residue.denoise_frame(frames, t)
        assert missing == ([-1] if t == 0 else [])
        assert np.array_equal(out, read_rgb(str(tmp_path / f"temporal.{t + 1:04d}.exr"))), t
    alone, _ = residue.denoise_frame(frames[1:2], 0)
    assert not np.array_equal(alone, residue.denoise_frame(frames, 1)[0]), "the neighbours change it"
    still, missing = residue.denoise_frame(frames, 1, model="tiny")  # a model for stills: the frame alone
    assert missing == [] and np.array_equal(still, residue.denoise(frames[1], "tiny"))
    with pytest.raises(residue.Error, match="t = 4"):
        residue.denoise_frame(frames, 4)


def test_temporal_blend_equals_the_clis(tmp_path):
    frames = [residue.load(os.path.join(SHOT, f"noisy.{i:04d}.exr")) for i in (1, 2, 3, 4)]
    assert all(f.motion is not None for f in frames)
    denoised = [residue.denoise(f, "tiny") for f in frames]
    pattern = str(tmp_path / "blend.####.exr")
    subprocess.run([CLI, "denoise", os.path.join(SHOT, "noisy.####.exr"), "--frames", "1-3", "-m", "tiny",
                    "--temporal-blend", "--float", "-o", pattern], check=True, capture_output=True)
    for t in (0, 1, 2):  # frame 1 has no frame before it; the CLI reads frame 4 beside frame 3, outside its range
        blended = residue.temporal_blend(frames, denoised, t)
        assert np.array_equal(blended, read_rgb(str(tmp_path / f"blend.{t + 1:04d}.exr"))), t
        assert not np.array_equal(blended, denoised[t]), "the neighbours change it"
    loose = residue.temporal_blend(frames, denoised, 1, tolerance=2.0)
    assert not np.array_equal(loose, residue.temporal_blend(frames, denoised, 1))
    assert np.array_equal(residue.temporal_blend(frames[:3], denoised[:3], 2),
                          residue.temporal_blend(frames[1:3], denoised[1:3], 1)), "the last frame given: one neighbour"
    with pytest.raises(residue.Error, match="t = 4"):
        residue.temporal_blend(frames, denoised, 4)
    with pytest.raises(residue.Error, match="2 denoised"):
        residue.temporal_blend(frames, denoised[:2], 0)
    still = residue.stack(frames[1].color)  # frame t without motion vectors
    with pytest.raises(residue.Error, match="motion"):
        residue.temporal_blend([frames[0], still], denoised[:2], 1)
