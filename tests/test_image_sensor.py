"""The image sensor (generator/image_sensor.py): the sRGB curve it uses, exposure, the noise
statistics of a flat grey patch against the documented model, JPEG, determinism; and on a
Simulator, that only the display colour changes."""

import io
import math

import numpy as np
import pytest
from PIL import Image

from generator.image_sensor import (CODES, IDEAL, ImageSensor, encode_codes, exposure_gain, image_sensor_of,
                                    srgb_decoding, view_stream)


def srgb_reference(v):
    """IEC 61966-2-1's decoding, with numpy's power (what the table must equal)."""
    v = np.asarray(v, np.float64)
    return np.where(v <= 0.04045, v / 12.92, ((v + 0.055) / 1.055) ** 2.4)


def flat(value_code: int, shape=(200, 300)):
    return np.full(shape + (3,), value_code / CODES, np.float32)


def test_the_srgb_table_is_the_standard_curve_and_encoding_inverts_it_on_every_code():
    table = srgb_decoding()
    codes = np.arange(CODES + 1)
    ref = srgb_reference(codes / CODES)
    assert np.max(np.abs(table - ref) / np.maximum(ref, 1e-300)) < 1e-14
    assert np.all(np.diff(table) > 0)
    assert np.array_equal(encode_codes(table, table), codes)
    out, gain = IDEAL.apply((codes[:65536 - 16].reshape(-1, 60, 3) / CODES).astype(np.float32)[:364], None)
    assert gain == 1.0 and np.array_equal(out, (codes[:65520].reshape(-1, 60, 3) / CODES).astype(np.float32)[:364])


@pytest.mark.parametrize("ev", [0.0, 1.0, -2.0, 0.5, -1.25, 2.7, 9.99])
def test_exposure_gain_is_two_to_the_stops(ev):
    assert math.isclose(exposure_gain(ev), 2.0 ** ev, rel_tol=1e-7)


def test_a_fixed_exposure_scales_the_linear_signal_and_saturates_at_full_well():
    table = srgb_decoding()
    code = 20000
    out, gain = ImageSensor(exposure_ev=1.0).apply(flat(code, (4, 4)), None)
    assert gain == 2.0
    got = table[np.rint(out.astype(np.float64) * CODES).astype(int)]
    assert np.allclose(got, 2.0 * table[code], rtol=1e-4)
    out, _ = ImageSensor(exposure_ev=3.0).apply(flat(50000, (4, 4)), None)
    assert np.all(out == 1.0)  # past full well


def test_auto_exposure_brings_the_mean_luminance_to_mid_grey_within_three_stops():
    table = srgb_decoding()
    code = int(np.searchsorted(table, 0.05))  # a dull scene, linear 0.05
    out, gain = ImageSensor(exposure_ev=None).apply(flat(code, (8, 8)), None)
    assert math.isclose(gain, 0.18 / table[code], rel_tol=1e-12)
    assert np.allclose(table[np.rint(out.astype(np.float64) * CODES).astype(int)], 0.18, rtol=1e-4)
    _, gain = ImageSensor(exposure_ev=None).apply(flat(10, (8, 8)), None)  # nearly black: the limit
    assert gain == 8.0


@pytest.mark.parametrize("linear,full_well,read", [(0.2, 2000.0, 5.0), (0.02, 2000.0, 5.0), (0.5, 20000.0, 2.0)])
def test_noise_of_a_flat_grey_patch_matches_the_documented_model(linear, full_well, read):
    """Mean x and variance (x FW + read^2) / FW^2 in the linear domain (docs/cameras.md), on
    180,000 samples: within five standard errors."""
    table = srgb_decoding()
    code = int(np.searchsorted(table, linear))
    x = table[code]
    sensor = ImageSensor(exposure_ev=0.0, full_well_e=full_well, read_noise_e=read)
    out, _ = sensor.apply(flat(code), view_stream(0, 1, np.eye(4)))
    values = table[np.rint(out.astype(np.float64) * CODES).astype(int)].ravel()
    n = len(values)
    variance = (x * full_well + read * read) / (full_well * full_well)
    assert abs(values.mean() - x) < 5 * math.sqrt(variance / n)
    assert abs(values.var() / variance - 1) < 5 * math.sqrt(2 / n)


def test_noise_is_the_same_bytes_for_the_same_view_and_differs_between_views():
    sensor = ImageSensor(exposure_ev=None, full_well_e=6000.0, read_noise_e=3.0)
    img = (np.random.default_rng(1).integers(0, CODES + 1, (32, 48, 3)) / CODES).astype(np.float32)
    pose = np.eye(4)
    a, _ = sensor.apply(img, view_stream(5, 3, pose))
    b, _ = sensor.apply(img, view_stream(5, 3, pose.copy()))
    pose[0, 3] = 0.1
    c, _ = sensor.apply(img, view_stream(5, 3, pose))
    d, _ = sensor.apply(img, view_stream(5, 4, np.eye(4)))
    assert a.tobytes() == b.tobytes() and not np.array_equal(a, c) and not np.array_equal(a, d)


def test_jpeg_is_pillows_round_trip_of_the_8_bit_image_and_costs_more_at_low_quality():
    rng = np.random.default_rng(2)
    smooth = np.cumsum(rng.normal(size=(64, 96, 3)), axis=1)
    img = ((smooth - smooth.min()) / np.ptp(smooth) * CODES).round() / CODES
    img = img.astype(np.float32)
    errors = []
    for q in (90, 20):
        out, _ = ImageSensor(jpeg_quality=q).apply(img, None)
        rgb8 = (np.clip(img, 0, 1) * 255 + 0.5).astype(np.uint8)
        buf = io.BytesIO()
        Image.fromarray(rgb8).save(buf, format="JPEG", quality=q)
        theirs = np.asarray(Image.open(buf).convert("RGB")) / np.float32(255)
        assert np.array_equal(out, theirs.astype(np.float32))
        errors.append(np.abs(out - img).mean())
    assert errors[0] < errors[1]


@pytest.mark.parametrize("args,message", [
    (("bright",), "exposure must be 'auto', 'as-rendered' or a number of stops"),
    ((11.0,), "exposure must be 'auto' or a number of stops from -10 to 10"),
    (("auto", (6000.0,)), "sensor noise is two numbers"),
    (("auto", (0.5, 3.0)), "full well must be 1 to 10,000,000 electrons"),
    (("auto", (), 0), "JPEG quality must be an integer from 1 to 100"),
])
def test_values_a_sensor_cannot_have_are_refused_in_one_line(args, message):
    with pytest.raises(ValueError, match=message):
        image_sensor_of(*args)


def test_as_dict_round_trips():
    for sensor in (IDEAL, ImageSensor(None, 6000.0, 3.0, 85), ImageSensor(-1.5)):
        assert ImageSensor.from_dict(sensor.as_dict()) == sensor


@pytest.fixture(scope="module")
def sensed(walls_blend):
    from generator import Simulator

    sim = Simulator(walls_blend, points_density=2.0, render_preset="preview")
    sim.configure_render(samples=8, resolution=(64, 48), denoise=False)
    clean = sim.render()
    sim.set_image_sensor("auto", full_well_e=4000.0, read_noise_e=4.0, jpeg_quality=80)
    noisy = sim.render()
    again = sim.render()
    return sim, clean, noisy, again


def test_only_the_display_colour_changes_on_a_simulator(sensed):
    sim, clean, noisy, again = sensed
    assert not np.array_equal(clean.rgb, noisy.rgb) and noisy.rgb.dtype == np.float32
    assert noisy.rgb.shape == clean.rgb.shape and 0 <= noisy.rgb.min() and noisy.rgb.max() <= 1
    for name in ("depth", "seg", "instance", "rgb_linear"):
        assert np.array_equal(getattr(clean, name), getattr(noisy, name), equal_nan=True), name
    assert clean.exposure_gain == 1.0 and 1 / 8 <= noisy.exposure_gain <= 8
    assert np.array_equal(noisy.rgb, again.rgb)  # the same view: the same noise
    # the sensor's output is the documented pipeline applied to the clean render
    expected, gain = sim.image_sensor.apply(clean.rgb, view_stream(sim.seed, clean.frame, clean.world_from_camera))
    assert np.array_equal(expected, noisy.rgb) and gain == noisy.exposure_gain
    with pytest.raises(ValueError, match="read noise needs a full well"):
        sim.set_image_sensor(read_noise_e=3.0)
