"""Issue 17, item 6: is `mitsuba.chi2`'s rejection of the presets at cos theta = 0.39 the
harness's resolution or the sampler? Runs Mitsuba's ChiSquareTest (llvm_ad_rgb) on the core's
own sample/pdf through the `lacquer` Python package (liblacquer via ctypes; no plugin build
needed), at the test's settings (res 64, ires 16) and at finer ones, and prints the statistic
per setting. Usage (from the repository root):

    LACQUER_LIBRARY=target/release/liblacquer.so DRJIT_LIBLLVM_PATH=/usr/lib/x86_64-linux-gnu/libLLVM.so.19.1 \
    PYTHONPATH=c-api/python .venv-tests/bin/python mitsuba-plugin/tools/chi2_resolution_probe.py [preset ...]

Samples use u[0] for the lobe choice and u[1..3] inside the lobe, as the plugin maps Mitsuba's
(sample1, sample2); failed samples get weight 0 and are dropped, as BSDFAdapter does.
"""

import sys
import time

import numpy as np
import drjit as dr
import mitsuba as mi

mi.set_variant("llvm_ad_rgb")
from mitsuba.chi2 import ChiSquareTest, SphericalDomain  # noqa: E402

import lacquer  # noqa: E402

WI = np.array([0.2, -0.9, 0.387])
WI = WI / np.linalg.norm(WI)
SETTINGS = [(64, 16), (64, 32), (128, 16), (128, 32), (256, 16)]


def functions(material):
    def sample_func(sample):
        u = np.stack([np.asarray(sample[i], dtype=np.float64) for i in range(3)], axis=-1)
        wo = np.broadcast_to(WI, u.shape).copy()
        s = material.sample(wo, u)
        ok = (s.pdf > 0) & np.any(s.weight > 0, axis=-1)
        wi = s.wi
        return mi.Vector3f(wi[:, 0], wi[:, 1], wi[:, 2]), mi.Float(ok.astype(np.float32))

    def pdf_func(wo_dirs):
        d = np.stack([np.asarray(wo_dirs[i], dtype=np.float64) for i in range(3)], axis=-1)
        wo = np.broadcast_to(WI, d.shape).copy()
        return mi.Float(material.pdf(d, wo, strict=False).astype(np.float32))

    return sample_func, pdf_func


def main():
    names = sys.argv[1:] or ["gold_flake_8", "silver_flake_2", "pearl_blue", "pearl_white",
                             "automotive_silver_metallic", "solid_red"]
    for name in names:
        m = lacquer.Material.preset(name)
        s, p = functions(m)
        for res, ires in SETTINGS:
            t = time.time()
            chi2 = ChiSquareTest(domain=SphericalDomain(), sample_func=s, pdf_func=p, sample_dim=3,
                                 sample_count=400_000, res=res, ires=ires)
            ok = chi2.run()
            # The statistic and dof are in the harness's messages.
            keep = ("Chi^2", "p-value", "Histogram sum", "Failure")
            msg = " ".join(l.strip() for l in chi2.messages.splitlines() if any(k in l for k in keep))
            print(f"{name} res {res} ires {ires}: {'pass' if ok else 'FAIL'} | {msg} ({time.time() - t:.0f} s)", flush=True)


if __name__ == "__main__":
    main()
