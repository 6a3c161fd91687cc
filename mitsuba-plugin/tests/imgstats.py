"""Image statistics for "agree within noise" tests, on EXR files read with OpenImageIO.

Two renders A and B of the same scene with independent (or differently used) random numbers
have the same expectation in every pixel, so D = A - B is pure noise with mean 0. Tests:

- image mean: z = mean(D) / (std(D) / sqrt(N)) over all N pixel values;
- per pixel: the image is cut into b x b blocks; in each block z_k = mean(D) / (std(D) / b).
  Under the hypothesis each z_k is roughly standard normal; a real difference confined to a
  region (a wrong highlight, a missing lobe) shows as blocks with |z| far above 4.
"""

import math

import numpy as np
import OpenImageIO as oiio


def read_exr(path):
    buf = oiio.ImageBuf(str(path))
    if buf.has_error:
        raise RuntimeError(buf.geterror())
    px = buf.get_pixels(oiio.FLOAT)
    return np.asarray(px, dtype=np.float64)[:, :, :3]


def channel_means(path):
    """Per-channel mean through OpenImageIO's own statistics."""
    buf = oiio.ImageBuf(str(path))
    stats = oiio.ImageBufAlgo.computePixelStats(buf)
    return list(stats.avg)[:3]


def compare(a, b, block=8, floor=1e-4):
    """Statistics of D = a - b; `floor` (relative to b's mean) is the float-rounding level below
    which a block difference counts as none (e.g. a background both render as exactly 0.6)."""
    a = np.asarray(a, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    assert a.shape == b.shape, (a.shape, b.shape)
    d = a - b
    n = d.size
    sd = d.std(ddof=1)
    z_mean = d.mean() / (sd / math.sqrt(n)) if sd > 0 else 0.0
    h, w = d.shape[0] // block * block, d.shape[1] // block * block
    blocks = d[:h, :w].reshape(h // block, block, w // block, block, -1).transpose(0, 2, 1, 3, 4)
    blocks = blocks.reshape(h // block, w // block, -1)
    bm = blocks.mean(axis=2)
    bs = blocks.std(axis=2, ddof=1)
    nb = blocks.shape[2]
    mean_a, mean_b = a.mean(), b.mean()
    eps = floor * abs(mean_b)
    z = bm / np.sqrt(bs**2 / nb + eps**2)
    return {
        "max_abs_diff_rel": float(np.max(np.abs(d)) / max(abs(mean_b), 1e-30)),
        "mean_a": mean_a,
        "mean_b": mean_b,
        "rel_mean_diff": (mean_a - mean_b) / mean_b if mean_b else float("nan"),
        "z_mean": z_mean,
        "max_block_z": float(np.max(np.abs(z))),
        "blocks_over_4": float(np.mean(np.abs(z) > 4.0)),
        "n_blocks": int(z.size),
    }


def assert_within_noise(stats, z_mean=5.0, block_frac=0.03, block_z=8.0):
    if stats["max_abs_diff_rel"] <= 1e-5:
        return  # identical up to float rounding (same sampling, same seed)
    msg = ", ".join(f"{k} = {v:.4g}" if isinstance(v, float) else f"{k} = {v}" for k, v in stats.items())
    assert abs(stats["z_mean"]) < z_mean, "image means differ beyond noise: " + msg
    assert stats["blocks_over_4"] <= block_frac, "too many blocks differ beyond 4 sigma: " + msg
    assert stats["max_block_z"] < block_z, "a block differs far beyond noise: " + msg
