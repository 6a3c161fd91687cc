"""Issue 14 item 1: the wheel `lacquer-mitsuba` (mitsuba-plugin/wheel.sh) and the version check.

The wheel is built from the plugins test.sh just built, installed into a scratch folder
(not the venv, whose .pth points at the source tree), and used from a fresh Python process
exactly as a user would: import, register(), an XML scene with typed properties and a bitmap
texture on base_color, a render in scalar_rgb, scalar_spectral, llvm_ad_rgb and
llvm_ad_spectral, and an edit
through mi.traverse that changes the render."""

import os
import shutil
import subprocess
import sys
import zipfile

import pytest

import mitsuba as mi

import lacquer_mitsuba
from conftest import REPO


def test_build_info_names_this_mitsuba():
    info = lacquer_mitsuba.build_info()
    assert info["mitsuba"] == mi.__version__
    assert {"scalar_rgb", "scalar_spectral"} <= set(info["variants"])
    # build.sh registers both llvm variants or neither (--no-llvm)
    assert ("llvm_ad_rgb" in info["variants"]) == ("llvm_ad_spectral" in info["variants"]), info


def test_version_mismatch_is_refused_by_name(scalar_rgb, monkeypatch):
    monkeypatch.setattr(lacquer_mitsuba, "build_info", lambda: {"mitsuba": "3.0.0", "variants": []})
    with pytest.raises(lacquer_mitsuba.LacquerError) as e:
        lacquer_mitsuba.register(fallback=False)
    assert "built for Mitsuba 3.0.0" in str(e.value) and mi.__version__ in str(e.value)


SCRIPT = r"""
import os, sys, numpy as np, mitsuba as mi, drjit as dr
mi.set_variant("scalar_rgb")
import lacquer_mitsuba
assert lacquer_mitsuba.__file__.startswith(sys.argv[1]), lacquer_mitsuba.__file__
# A 2x2 linear-RGB livery for base_color (issue 14's user: typed properties and a bitmap).
mi.Bitmap(np.array([[[0.5, 0.1, 0.05], [0.1, 0.2, 0.6]]] * 2, dtype=np.float32)).write("livery.exr")
XML = '''<scene version="3.0.0">
  <integrator type="direct"/>
  <sensor type="perspective">
    <transform name="to_world"><lookat origin="0, -3, 2.5" target="0, 0, 0" up="0, 0, 1"/></transform>
    <film type="hdrfilm"><integer name="width" value="16"/><integer name="height" value="16"/></film>
    <sampler type="independent"><integer name="sample_count" value="4"/></sampler>
  </sensor>
  <shape type="rectangle" id="plane">
    <bsdf type="lacquer">
      <string name="model" value="coated_paint"/>
      <texture type="bitmap" name="base_color">
        <string name="filename" value="livery.exr"/>
        <boolean name="raw" value="true"/>
      </texture>
      <float name="flake_density" value="5"/>
      <boolean name="sparkle" value="false"/>
    </bsdf>
  </shape>
  <emitter type="point"><point name="position" x="1" y="-1" z="2"/><rgb name="intensity" value="8"/></emitter>
</scene>'''
variants = ["scalar_rgb", "scalar_spectral"] + (["llvm_ad_rgb", "llvm_ad_spectral"] if os.environ.get("DRJIT_LIBLLVM_PATH") else [])
for v in variants:
    mi.set_variant(v)
    assert lacquer_mitsuba.register(fallback=False) == "native"
    scene = mi.load_string(XML)
    def render():
        if v.startswith("llvm"):
            with lacquer_mitsuba.wavefront():
                return np.array(mi.render(scene, seed=1))
        return np.array(mi.render(scene, seed=1))
    img = render()
    assert np.all(np.isfinite(img)) and img.mean() > 0, v
    params = mi.traverse(scene)
    params["plane.bsdf.flake_density"] = 30.0
    params.update()
    assert np.abs(render() - img).mean() > 1e-3 * img.mean(), v
print("ok", " ".join(variants))
"""


def test_wheel_installs_and_renders(tmp_path):
    dist, site, src = tmp_path / "dist", tmp_path / "site", tmp_path / "src"
    # built from a copy: setuptools writes build/ next to the sources
    shutil.copytree(REPO / "mitsuba-plugin" / "python", src, ignore=shutil.ignore_patterns("__pycache__", "build"))
    subprocess.run([sys.executable, "-m", "pip", "wheel", "-q", "--disable-pip-version-check", "--no-deps",
                    "-w", str(dist), str(src)], check=True)
    wheels = list(dist.glob("lacquer_mitsuba-*.whl"))
    assert len(wheels) == 1 and "-py3-none-linux_x86_64" in wheels[0].name, wheels
    names = zipfile.ZipFile(wheels[0]).namelist()
    for f in ("plugins/lacquer.so", "plugins/lacquer_path.so", "plugins/build_info.json", "__init__.py"):
        # (setuptools files a platform wheel's package under lacquer_mitsuba-*.data/purelib/;
        # pip installs it into site-packages all the same)
        assert any(n.endswith(f"lacquer_mitsuba/{f}") for n in names), f
    meta = zipfile.ZipFile(wheels[0]).read(next(n for n in names if n.endswith("METADATA"))).decode()
    assert f"Requires-Dist: mitsuba=={mi.__version__}" in meta
    subprocess.run([sys.executable, "-m", "pip", "install", "-q", "--disable-pip-version-check", "--no-deps",
                    "--target", str(site), str(wheels[0])], check=True)
    env = dict(os.environ, PYTHONPATH=str(site))
    r = subprocess.run([sys.executable, "-c", SCRIPT, str(site)], env=env, capture_output=True, text=True,
                       cwd=tmp_path)
    assert r.returncode == 0 and r.stdout.startswith("ok"), r.stdout + r.stderr
    # every variant issue 14's "done when" names (llvm when Dr.Jit has its LLVM, as in CI)
    want = "ok scalar_rgb scalar_spectral" + (" llvm_ad_rgb llvm_ad_spectral" if os.environ.get("DRJIT_LIBLLVM_PATH") else "")
    assert r.stdout.strip() == want, r.stdout
