"""Issue 14 item 1: scenes find `lacquer` without `register()` after one documented step,
`python -m lacquer_mitsuba install`, which links the native plugins into Mitsuba's own plugin
folder. Mitsuba's file resolver searches the working directory first and then its package
folder, whose `plugins/` holds its built-in plugins; the test links into a scratch folder's
`plugins/` and runs a fresh process there (so the shared venv's Mitsuba is not modified while
other tests run), and checks separately that the default target is the folder of Mitsuba's
own plugins."""

import os
import subprocess
import sys

import pytest

import mitsuba as mi

import lacquer_mitsuba

SCRIPT = r"""
import sys, numpy as np, mitsuba as mi
mi.set_variant(sys.argv[1])
scene = mi.load_string('''<scene version="3.0.0">
  <integrator type="direct"/>
  <sensor type="perspective">
    <transform name="to_world"><lookat origin="0, -3, 2.5" target="0, 0, 0" up="0, 0, 1"/></transform>
    <film type="hdrfilm"><integer name="width" value="16"/><integer name="height" value="16"/></film>
    <sampler type="independent"><integer name="sample_count" value="4"/></sampler>
  </sensor>
  <shape type="rectangle">
    <bsdf type="lacquer">
      <string name="model" value="coated_paint"/>
      <float name="pearl_density" value="20"/>
    </bsdf>
  </shape>
  <emitter type="point"><point name="position" x="1" y="-1" z="2"/><rgb name="intensity" value="8"/></emitter>
</scene>''')
img = np.array(mi.render(scene))
assert np.all(np.isfinite(img)) and img.mean() > 0
assert "lacquer_mitsuba" not in sys.modules
print("ok", img.mean())
"""


def test_default_target_is_mitsubas_plugin_folder():
    d = lacquer_mitsuba.mitsuba_plugin_dir()
    assert os.path.isfile(os.path.join(d, "diffuse.so")), d
    assert os.path.dirname(d) == os.path.dirname(mi.__file__)


@pytest.mark.parametrize("variant", ["scalar_rgb", "scalar_spectral"])
def test_installed_plugin_loads_from_xml_without_register(tmp_path, variant):
    plugins = tmp_path / "plugins"
    plugins.mkdir()
    made = lacquer_mitsuba.install(str(plugins))
    assert sorted(os.path.basename(p) for p in made) == ["lacquer.so", "lacquer_path.so"]
    assert all(os.path.realpath(p).startswith(lacquer_mitsuba.plugin_dir()) for p in made)
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}  # lacquer_mitsuba not needed
    r = subprocess.run([sys.executable, "-c", SCRIPT, variant], cwd=tmp_path, env=env, capture_output=True,
                       text=True)
    assert r.returncode == 0 and r.stdout.startswith("ok"), r.stdout + r.stderr
    # Without the links the same scene fails: it was the install that made the plugin visible.
    assert lacquer_mitsuba.uninstall(str(plugins)) == made
    r = subprocess.run([sys.executable, "-c", SCRIPT, variant], cwd=tmp_path, env=env, capture_output=True,
                       text=True)
    assert r.returncode != 0 and "lacquer" in r.stderr


def test_install_refuses_another_mitsuba(tmp_path, monkeypatch):
    monkeypatch.setattr(lacquer_mitsuba, "build_info", lambda: {"mitsuba": "3.0.0"})
    with pytest.raises(lacquer_mitsuba.LacquerError) as e:
        lacquer_mitsuba.install(str(tmp_path))
    assert "built for Mitsuba 3.0.0" in str(e.value)
    assert not os.listdir(tmp_path)


def test_install_does_not_replace_a_real_file(tmp_path):
    (tmp_path / "lacquer.so").write_text("not ours")
    with pytest.raises(lacquer_mitsuba.LacquerError):
        lacquer_mitsuba.install(str(tmp_path))
    assert (tmp_path / "lacquer.so").read_text() == "not ours"
