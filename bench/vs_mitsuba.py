#!/usr/bin/env python3
"""Lacquer (C ABI, liblacquer.so through ctypes) against Mitsuba 3's built-in BSDFs
(`llvm_ad_rgb`) on identical inputs, in one process: first pinned to one core, then on all
cores. Prints ns/element and the ratio Lacquer / Mitsuba (min and median of the repetitions).

    python3 bench/vs_mitsuba.py                  # from the repository root; sets itself up (~2 min)
    python3 bench/vs_mitsuba.py --quick          # CI smoke run: n = 1e5, 3 repetitions
    python3 bench/vs_mitsuba.py --json out.json  # also write every timing as JSON

Set-up (done by the script, idempotent): the pinned venv of scripts/python-env.sh
(.venv-tests: numpy, Mitsuba 3.9.1), libllvm19 with apt-get when missing (Dr.Jit's llvm
backend aborts with Debian's LLVM 15; needs root) and DRJIT_LIBLLVM_PATH, and liblacquer.so:
$LACQUER_LIBRARY (built elsewhere: the report says its commit is unknown), else
$CARGO_TARGET_DIR or target/release/liblacquer.so, which the script brings up to date with
`cargo build --release -p lacquer-capi -p lacquer-cli` on every run (a no-op of about a second
when nothing changed), so the git commit it prints is the one the library was built from. The
script then re-executes itself in the venv.

What is compared (same work on both sides):
  * Inputs: n direction pairs, both cosine-distributed in the upper hemisphere, and n
    triples of uniform numbers u in [0, 1), float32, fixed seed. Every side reads the same
    float32 values: Lacquer the numpy arrays in place (interleaved xyz, and separate x/y/z
    arrays for the structure-of-arrays entry points when the library has them), Mitsuba
    Dr.Jit copies of the same arrays made before timing (checked bit for bit).
  * Conventions: Lacquer's wo (toward the viewer) is Mitsuba's si.wi, Lacquer's wi (toward
    the light) is the `wo` argument of Mitsuba's eval/pdf. Mitsuba's eval includes the
    cosine of the light direction, Lacquer's does not; sample weights are f·cos/pdf in both.
    For sampling, Lacquer's u = (u0, u1, u2) is Mitsuba's sample1 = u0 and
    sample2 = (u1, u2).
  * Timed region: one batch call over all n elements. Lacquer: lq_eval / lq_pdf /
    lq_sample (or the _soa variants) into preallocated numpy arrays (no copies). Mitsuba:
    bsdf.eval / pdf / sample followed by dr.eval of the same outputs (f; pdf; wi, weight and
    pdf of the sample) and dr.sync_thread(), i.e. tracing plus running the kernel. Kernels
    are compiled (and cached) in untimed warm-up calls. Lacquer and Mitsuba repetitions
    alternate so that machine load hits both alike, with a pause of --pause seconds (default
    0.03) before each call so that the other library's idle workers have stopped spinning.
  * Check column: where the two BRDFs are the same model, the largest relative difference
    between the two results (eval compared as Lacquer f·cos θi against Mitsuba's eval; a
    sample is checked by evaluating Mitsuba's eval and pdf at Lacquer's sampled direction and
    comparing Lacquer's weight and pdf with them, because the two map u to directions
    differently for GGX: same density, different warp; the cosine-weighted diffuse lobes draw
    the same directions). Values below 1e-6 of the largest value
    are compared absolutely against that floor. `principled` and the paint presets are not
    the same BRDF as Mitsuba's `principled`: those rows compare the cost of comparable work.
"""

import argparse
import ctypes
import gc
import glob
import json
import os
import pathlib
import platform
import shutil
import statistics
import subprocess
import sys
import time

ROOT = pathlib.Path(__file__).resolve().parent.parent
CHILD_MARK = "LACQUER_VS_MITSUBA_CHILD"

# Gold, lacquer's rust-core/src/fresnel.rs METALS "Au" (RGB n and k), given to both sides.
AU_ETA = [0.143119, 0.374957, 1.44248]
AU_K = [3.98316, 2.38572, 1.60322]

PAINT_PRESETS = ["gold_flake_8", "silver_flake_8", "solid_red", "pearl_white"]


def log(msg):
    print(msg, file=sys.stderr, flush=True)


# --------------------------------------------------------------------------------------------
# Set-up (runs under any python3; stdlib only), then re-exec in the venv.
# --------------------------------------------------------------------------------------------

def find_libllvm19():
    """Path of LLVM 19's shared library, installing libllvm19 with apt-get if missing."""
    given = os.environ.get("DRJIT_LIBLLVM_PATH")
    if given and os.path.isfile(given):
        return given
    pattern = "/usr/lib/*-linux-gnu/libLLVM.so.19*"
    found = sorted(glob.glob(pattern))
    if not found and shutil.which("apt-get") and os.geteuid() == 0:
        log("installing libllvm19 with apt-get (Dr.Jit's llvm backend aborts with LLVM 15)")
        env = dict(os.environ, DEBIAN_FRONTEND="noninteractive")
        subprocess.run(["apt-get", "update", "-qq"], check=True, stdout=sys.stderr, env=env)
        subprocess.run(["apt-get", "install", "-y", "-qq", "libllvm19"], check=True, stdout=sys.stderr, env=env)
        found = sorted(glob.glob(pattern))
    if not found:
        sys.exit("libLLVM 19 not found: install libllvm19 (apt-get install libllvm19, as root) "
                 "or set DRJIT_LIBLLVM_PATH")
    return found[0]


def find_or_build_library():
    """The library to time and where it comes from: $LACQUER_LIBRARY as given, else this tree's
    release build, brought up to date first (cargo rebuilds only what changed), so that a
    library older than the checked-out sources is never timed under the tree's git commit."""
    given = os.environ.get("LACQUER_LIBRARY")
    if given:
        if not os.path.isfile(given):
            sys.exit(f"LACQUER_LIBRARY={given} does not exist")
        return given, "given by LACQUER_LIBRARY: its commit is unknown"
    target = pathlib.Path(os.environ.get("CARGO_TARGET_DIR") or ROOT / "target")
    lib = target / "release" / "liblacquer.so"
    # With the CLI, to share its build (same dependency features; docs/reliability.md).
    log("cargo build --release -p lacquer-capi -p lacquer-cli (brings target/release/liblacquer.so up to date)")
    subprocess.run(["cargo", "build", "--release", "-p", "lacquer-capi", "-p", "lacquer-cli"], cwd=ROOT, check=True,
                   stdout=sys.stderr)
    return str(lib), "built from this tree by the script"


def bootstrap():
    """Prepare the environment and re-execute this script inside the venv."""
    proc = subprocess.run(["bash", str(ROOT / "scripts" / "python-env.sh")], check=True,
                          stdout=subprocess.PIPE, text=True)
    venv = proc.stdout.strip().splitlines()[-1]
    library, source = find_or_build_library()
    env = dict(os.environ, DRJIT_LIBLLVM_PATH=find_libllvm19(), LACQUER_LIBRARY=library, LACQUER_LIBRARY_SOURCE=source)
    env[CHILD_MARK] = "1"
    python = os.path.join(venv, "bin", "python")
    os.execve(python, [python, os.path.abspath(__file__), *sys.argv[1:]], env)


# --------------------------------------------------------------------------------------------
# Machine control: affinity of every thread of the process, thread counts of both libraries.
# --------------------------------------------------------------------------------------------

def set_process_affinity(cpus):
    """os.sched_setaffinity(0, ...) pins only the calling thread; pin every existing thread
    (Dr.Jit's and Lacquer's workers included). Threads created later inherit it."""
    for tid in os.listdir("/proc/self/task"):
        try:
            os.sched_setaffinity(int(tid), cpus)
        except ProcessLookupError:  # a thread that ended meanwhile
            pass


def machine_info():
    cpu = platform.processor() or "unknown CPU"
    flags = set()
    # Family and model tell CPU generations apart where the model name does not (a VM's
    # "AMD EPYC" was Zen 3 without AVX-512 in some sessions and Zen 4 with it in others).
    family = model = None
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                key, _, value = line.partition(":")
                key, value = key.strip(), value.strip()
                if key == "cpu family":
                    family = value
                elif key == "model":
                    model = value
                elif key == "model name":
                    cpu = value
                elif key == "flags":
                    flags = set(value.split())
                    break
    except OSError:
        pass
    if family is not None and model is not None:
        cpu = f"{cpu} (family {family}, model {model})"
    simd = [x for x in ("avx2", "fma", "avx512f") if x in flags]
    return {"cpu": cpu, "logical_cpus": os.cpu_count(), "allowed_cpus": sorted(os.sched_getaffinity(0)),
            "simd": simd, "system": f"{platform.system()} {platform.release()}",
            "load_average_start": os.getloadavg()}


# --------------------------------------------------------------------------------------------
# Lacquer through the C ABI.
# --------------------------------------------------------------------------------------------

class Lacquer:
    """Thin ctypes binding of the batch calls used here (signatures as in
    c-api/include/lacquer.h). Arrays are passed as raw pointers into numpy arrays."""

    def __init__(self, path):
        L = self.lib = ctypes.CDLL(path)
        P, N = ctypes.c_void_p, ctypes.c_size_t
        L.lq_version.restype = ctypes.c_char_p
        L.lq_abi_version.restype = ctypes.c_uint32
        L.lq_last_error.restype = ctypes.c_char_p
        L.lq_material_from_json.argtypes = [ctypes.c_char_p, ctypes.POINTER(P)]
        L.lq_material_free.argtypes = [P]
        L.lq_material_free.restype = None
        # Interleaved (the current API): directions and RGB as xyz per element.
        sigs = {"lq_eval": [P, N, P, P, P], "lq_pdf": [P, N, P, P, P],
                "lq_sample": [P, N, P, P, P, P, P]}
        # Structure of arrays (when the library has them): one array per component, an
        # optional active mask (NULL = all active).
        self.has_soa = all(hasattr(L, s) for s in ("lq_eval_soa", "lq_pdf_soa", "lq_sample_soa"))
        if self.has_soa:
            sigs.update({"lq_eval_soa": [P, N] + [P] * 7 + [P] * 3,
                         "lq_pdf_soa": [P, N] + [P] * 7 + [P],
                         "lq_sample_soa": [P, N] + [P] * 7 + [P] * 8})
        for name, argtypes in sigs.items():
            fn = getattr(L, name)
            fn.argtypes, fn.restype = argtypes, ctypes.c_int32
        self.has_thread_count = hasattr(L, "lq_set_thread_count")
        if self.has_thread_count:
            L.lq_set_thread_count.argtypes, L.lq_set_thread_count.restype = [ctypes.c_uint32], None
        self.version = L.lq_version().decode()
        abi = L.lq_abi_version()
        self.abi = f"{abi >> 16}.{abi & 0xFFFF}"

    def check(self, status, what):
        if status != 0:
            raise RuntimeError(f"{what}: status {status}: {self.lib.lq_last_error().decode()}")

    def material(self, spec):
        handle = ctypes.c_void_p()
        self.check(self.lib.lq_material_from_json(json.dumps(spec).encode(), ctypes.byref(handle)),
                   f"lq_material_from_json({spec})")
        return handle

    def free(self, handle):
        self.lib.lq_material_free(handle)

    def set_threads(self, n):
        if self.has_thread_count:
            self.lib.lq_set_thread_count(n)


def ptr(a):
    return ctypes.c_void_p(a.ctypes.data)


# --------------------------------------------------------------------------------------------
# The comparisons: (name, Lacquer material, Mitsuba dict, same model?).
# --------------------------------------------------------------------------------------------

def cases(mi_rgb):
    """Lacquer material JSON and the Mitsuba BSDF dict it is compared with. `check` says
    which outputs must agree (same model) or None (comparable work only)."""
    out = [
        ("GGX conductor (Au, α 0.2)",
         {"model": "rough_conductor", "distribution": "ggx", "alpha_u": 0.2, "alpha_v": 0.2,
          "eta": AU_ETA, "k": AU_K, "sample_visible": True},
         {"type": "roughconductor", "distribution": "ggx", "alpha": 0.2, "sample_visible": True,
          "eta": mi_rgb(AU_ETA), "k": mi_rgb(AU_K)},
         "same model (to 1e-4 in mitsuba-plugin/tests/test_vs_builtin.py)"),
        # As test_rough_plastic_ggx_vs_roughplastic: by design Mitsuba integrates the coating's
        # transmittance in single precision (eval differs by ~4e-4, pdf by ~3e-3).
        ("rough_plastic vs roughplastic (GGX α 0.2)",
         {"model": "rough_plastic", "distribution": "ggx", "alpha": 0.2, "int_ior": 1.5,
          "ext_ior": 1.0, "diffuse_reflectance": [0.2, 0.4, 0.7], "nonlinear": False,
          "sample_visible": True},
         {"type": "roughplastic", "distribution": "ggx", "alpha": 0.2, "int_ior": 1.5, "ext_ior": 1.0,
          "diffuse_reflectance": mi_rgb([0.2, 0.4, 0.7]), "nonlinear": False, "sample_visible": True},
         "same model (by design: eval ≤ 1e-3, pdf ≤ 5e-3, test_vs_builtin.py)"),
        ("lambert vs diffuse",
         {"model": "lambert", "albedo": [0.2, 0.5, 0.8]},
         {"type": "diffuse", "reflectance": mi_rgb([0.2, 0.5, 0.8])},
         "same model"),
        # Blender's Principled (Lacquer) vs Disney's (Mitsuba): same inputs, different BRDFs.
        # Mitsuba's specular 0.5 is F0 = 0.08 * 0.5 = 0.04, i.e. Lacquer's ior 1.5 at
        # specular_ior_level 0.5. metallic 0.5 makes both evaluate every lobe.
        ("principled vs principled",
         {"model": "principled", "base_color": [0.8, 0.3, 0.2], "roughness": 0.5, "metallic": 0.5,
          "ior": 1.5, "specular_ior_level": 0.5},
         {"type": "principled", "base_color": mi_rgb([0.8, 0.3, 0.2]), "roughness": 0.5,
          "metallic": 0.5, "specular": 0.5},
         None),
    ]
    # Paint presets against Mitsuba's most complete opaque principled: diffuse + specular +
    # metal + clearcoat (all lobes on). Not the same BRDF: the cost of comparable work.
    coated = {"type": "principled", "base_color": mi_rgb([0.8, 0.5, 0.2]), "roughness": 0.3,
              "metallic": 0.5, "specular": 0.5, "clearcoat": 1.0, "clearcoat_gloss": 0.95}
    for p in PAINT_PRESETS:
        out.append((f"{p} vs principled+clearcoat", {"preset": p}, coated, None))
    return out


# --------------------------------------------------------------------------------------------
# Inputs.
# --------------------------------------------------------------------------------------------

def make_inputs(np, n, seed):
    """Cosine-distributed wi and wo (z > 0) and uniform u, float32, interleaved (n, 3) and
    as separate contiguous component arrays holding the same values."""
    rng = np.random.default_rng(seed)

    def cosine_hemisphere():
        u1, u2 = rng.random(n), rng.random(n)   # [0, 1): z = sqrt(1 - u1) > 0
        r, phi = np.sqrt(u1), 2.0 * np.pi * u2
        return np.stack([r * np.cos(phi), r * np.sin(phi), np.sqrt(1.0 - u1)], axis=1).astype(np.float32)

    wi, wo = cosine_hemisphere(), cosine_hemisphere()
    u = rng.random((n, 3), dtype=np.float32)
    soa = lambda a: [np.ascontiguousarray(a[:, i]) for i in range(3)]
    return {"wi": wi, "wo": wo, "u": u, "wi_soa": soa(wi), "wo_soa": soa(wo), "u_soa": soa(u)}


# --------------------------------------------------------------------------------------------
# Benchmark of one case: Lacquer and Mitsuba closures over the same inputs.
# --------------------------------------------------------------------------------------------

class Case:
    """One Lacquer material and one Mitsuba BSDF over the same inputs: closures that run one
    batch call (timed), and the check of the last call's outputs (untimed)."""

    def __init__(self, np, dr, mi, lq, inp, name, lq_spec, mi_spec, same_model):
        self.np, self.dr, self.mi, self.lq = np, dr, mi, lq
        self.name, self.same_model = name, same_model
        self.lq_spec, self.mi_spec = lq_spec, mi_spec
        n = self.n = len(inp["wi"])
        self.inp = inp
        self.m = lq.material(lq_spec)
        self.bsdf = mi.load_dict(mi_spec)

        # Lacquer outputs, allocated once.
        f32 = np.float32
        self.o = {"f": np.zeros((n, 3), f32), "pdf": np.zeros(n, f32), "wi": np.zeros((n, 3), f32),
                  "w": np.zeros((n, 3), f32), "spdf": np.zeros(n, f32)}
        self.o_soa = {k: [np.zeros(n, f32) for _ in range(3)] for k in ("f", "wi", "w")}
        self.o_soa.update({"pdf": np.zeros(n, f32), "spdf": np.zeros(n, f32)})

        # Mitsuba inputs: Dr.Jit copies of the SoA arrays, evaluated before any timing.
        wi, wo, u = inp["wi_soa"], inp["wo_soa"], inp["u_soa"]
        self.ctx = mi.BSDFContext()
        self.si = dr.zeros(mi.SurfaceInteraction3f)
        self.si.wi = mi.Vector3f(*[mi.Float(c) for c in wo])   # Mitsuba's si.wi = Lacquer's wo
        self.mwo = mi.Vector3f(*[mi.Float(c) for c in wi])     # Mitsuba's wo = Lacquer's wi
        self.s1 = mi.Float(u[0])
        self.s2 = mi.Point2f(mi.Float(u[1]), mi.Float(u[2]))
        dr.eval(self.si, self.mwo, self.s1, self.s2)
        dr.sync_thread()
        for a, b in ((self.si.wi, wo), (self.mwo, wi)):
            assert all(np.array_equal(np.array(a)[i], b[i]) for i in range(3)), "Mitsuba inputs differ"
        s2 = np.array(self.s2)
        assert np.array_equal(np.array(self.s1), u[0]) and np.array_equal(s2[0], u[1]) and \
            np.array_equal(s2[1], u[2]), "Mitsuba sample inputs differ"

    # One call each; every closure runs the whole batch. -------------------------------------

    def lacquer_fn(self, op, soa):
        L, m, n, inp = self.lq.lib, self.m, ctypes.c_size_t(self.n), self.inp
        if not soa:
            o = self.o
            if op == "eval":
                args = (m, n, ptr(inp["wi"]), ptr(inp["wo"]), ptr(o["f"]))
                fn = L.lq_eval
            elif op == "pdf":
                args = (m, n, ptr(inp["wi"]), ptr(inp["wo"]), ptr(o["pdf"]))
                fn = L.lq_pdf
            else:
                args = (m, n, ptr(inp["wo"]), ptr(inp["u"]), ptr(o["wi"]), ptr(o["w"]), ptr(o["spdf"]))
                fn = L.lq_sample
        else:
            o = self.o_soa
            wi, wo, u = [ptr(a) for a in inp["wi_soa"]], [ptr(a) for a in inp["wo_soa"]], [ptr(a) for a in inp["u_soa"]]
            if op == "eval":
                args = (m, n, *wi, *wo, None, *[ptr(a) for a in o["f"]])
                fn = L.lq_eval_soa
            elif op == "pdf":
                args = (m, n, *wi, *wo, None, ptr(o["pdf"]))
                fn = L.lq_pdf_soa
            else:
                args = (m, n, *wo, *u, None, *[ptr(a) for a in o["wi"]], *[ptr(a) for a in o["w"]],
                        ptr(o["spdf"]), None)
                fn = L.lq_sample_soa
        what = f"{fn.__name__} on {self.lq_spec}"

        def run():
            self.lq.check(fn(*args), what)
        return run

    def mitsuba_fn(self, op):
        dr, bsdf, ctx, si = self.dr, self.bsdf, self.ctx, self.si
        if op == "eval":
            def run():
                self.mf = bsdf.eval(ctx, si, self.mwo)
                dr.eval(self.mf)
                dr.sync_thread()
        elif op == "pdf":
            def run():
                self.mpdf = bsdf.pdf(ctx, si, self.mwo)
                dr.eval(self.mpdf)
                dr.sync_thread()
        else:
            def run():
                bs, w = bsdf.sample(ctx, si, self.s1, self.s2)
                self.ms = (bs.wo, w, bs.pdf)   # the outputs Lacquer writes: wi, weight, pdf
                dr.eval(*self.ms)
                dr.sync_thread()
        return run

    # Identical-work check (outside timing). -------------------------------------------------

    def check(self, op, soa):
        """Largest relative difference Lacquer vs Mitsuba for this op, or None when the two
        are not the same model."""
        if self.same_model is None:
            return None
        np, dr, mi = self.np, self.dr, self.mi
        o = self.o_soa if soa else self.o
        col = (lambda a: np.stack(a, axis=1)) if soa else (lambda a: a)
        wi_z = self.inp["wi"][:, 2].astype(np.float64)
        if op == "eval":
            ours = col(o["f"]).astype(np.float64) * wi_z[:, None]   # Mitsuba's eval has the cosine
            return rel_diff(np, ours, np.array(self.mf, dtype=np.float64).T)
        if op == "pdf":
            return rel_diff(np, o["pdf"].astype(np.float64), np.array(self.mpdf, dtype=np.float64))
        # sample: Mitsuba's eval and pdf at Lacquer's sampled direction.
        swi = col(o["wi"])
        ok = o["spdf"] > 0
        wi_m = mi.Vector3f(*[mi.Float(np.ascontiguousarray(swi[ok, i])) for i in range(3)])
        si = dr.zeros(mi.SurfaceInteraction3f)
        si.wi = mi.Vector3f(*[mi.Float(np.ascontiguousarray(c[ok])) for c in self.inp["wo_soa"]])
        f_m, p_m = self.bsdf.eval_pdf(self.ctx, si, wi_m)
        dr.eval(f_m, p_m)
        f_m, p_m = np.array(f_m, dtype=np.float64).T, np.array(p_m, dtype=np.float64)
        w_ref = np.where(p_m[:, None] > 0, f_m / np.where(p_m > 0, p_m, 1.0)[:, None], 0.0)
        return max(rel_diff(np, o["spdf"][ok].astype(np.float64), p_m),
                   rel_diff(np, col(o["w"])[ok].astype(np.float64), w_ref))

    def free(self):
        self.lq.free(self.m)


def rel_diff(np, ours, ref):
    """max |ours - ref| / max(|ref|, 1e-6 · max |ref|)."""
    floor = 1e-6 * float(np.max(np.abs(ref))) or 1e-30
    return float(np.max(np.abs(ours - ref) / np.maximum(np.abs(ref), floor)))


def summarise(row, n):
    """ns/element (min, median) of each side and the ratios, as printed."""
    out = {}
    m_min, m_med = min(row["mitsuba_ns"]) / n, statistics.median(row["mitsuba_ns"]) / n
    out["mitsuba_ns_per_elem"] = {"min": m_min, "median": m_med}
    for key in ("lacquer_ns", "lacquer_soa_ns"):
        if key in row:
            l_min, l_med = min(row[key]) / n, statistics.median(row[key]) / n
            out[key + "_per_elem"] = {"min": l_min, "median": l_med}
            out[key.replace("_ns", "") + "_ratio"] = {"min": l_min / m_min, "median": l_med / m_med}
    return out


# Seconds between two timed calls (--pause).
PAUSE_S = 0.03


def time_alternating(fns, reps, warmup=2):
    """Run each closure `warmup` times untimed, then `reps` rounds of one call each, in
    turn; returns the wall times (ns) per closure."""
    for fn in fns.values():
        for _ in range(warmup):
            fn()
    times = {k: [] for k in fns}
    gc.disable()
    try:
        for _ in range(reps):
            for k, fn in fns.items():
                # Both libraries' worker pools spin for a while after a call before they
                # sleep (Dr.Jit's nanothread, rayon): a pause keeps one library's idle
                # workers from taking the cores the next measured call runs on.
                time.sleep(PAUSE_S)
                t0 = time.perf_counter_ns()
                fn()
                times[k].append(time.perf_counter_ns() - t0)
    finally:
        gc.enable()
    return times


def memory_floor(np, inp, reps):
    """The least any eval can do: read the 6 direction floats and write 3 floats per element
    (numpy's add, single-threaded, no temporaries)."""
    out = np.empty_like(inp["wi"])
    t = time_alternating({"floor": lambda: np.add(inp["wi"], inp["wo"], out=out)}, reps)
    return t["floor"]


# --------------------------------------------------------------------------------------------
# One pass (one core or all cores).
# --------------------------------------------------------------------------------------------

def run_pass(np, dr, mi, lq, inp, reps, label, cpus, dr_threads, lq_threads):
    log(f"== {label}: cpus {sorted(cpus)}, Dr.Jit threads {dr_threads}, "
        f"lq_set_thread_count({lq_threads}){'' if lq.has_thread_count else ' (absent in this library)'}")
    set_process_affinity(set(os.sched_getaffinity(0)) | set(cpus))  # widen first, then narrow
    dr.set_thread_count(dr_threads)
    lq.set_threads(lq_threads)
    set_process_affinity(set(cpus))

    n = len(inp["wi"])
    rows = []
    mi_rgb = lambda v: {"type": "rgb", "value": v}
    for name, lq_spec, mi_spec, same in cases(mi_rgb):
        c = Case(np, dr, mi, lq, inp, name, lq_spec, mi_spec, same)
        for op in ("eval", "pdf", "sample"):
            fns = {"lacquer": c.lacquer_fn(op, soa=False), "mitsuba": c.mitsuba_fn(op)}
            if lq.has_soa:
                fns["lacquer_soa"] = c.lacquer_fn(op, soa=True)
            t = time_alternating(fns, reps)
            row = {"case": name, "op": op, "lacquer_material": lq_spec, "mitsuba_bsdf": mi_spec,
                   "same_model": same, "mitsuba_ns": t["mitsuba"], "lacquer_ns": t["lacquer"],
                   "check": c.check(op, soa=False)}
            if lq.has_soa:
                row["lacquer_soa_ns"] = t["lacquer_soa"]
                row["check_soa"] = c.check(op, soa=True)
            row["summary"] = summarise(row, n)
            rows.append(row)
            log(f"   {name}: {op}: Lacquer {min(t['lacquer']) / n:.1f} ns, "
                f"Mitsuba {min(t['mitsuba']) / n:.1f} ns")
        c.free()
    floor = memory_floor(np, inp, reps)
    return {"label": label, "cpus": sorted(cpus), "drjit_threads": dr_threads,
            "lacquer_threads": lq_threads if lq.has_thread_count else None,
            "rows": rows, "memory_floor_ns": floor, "load_average_after": os.getloadavg()}


# --------------------------------------------------------------------------------------------
# Report.
# --------------------------------------------------------------------------------------------

def fmt_check(x):
    return "—" if x is None else f"{x:.1e}"


def print_pass(p, n, one_core=None):
    per = lambda ts: (min(ts) / n, statistics.median(ts) / n)
    print(f"\n### {p['label']}: cpus {p['cpus']}, Dr.Jit threads {p['drjit_threads']}, Lacquer threads "
          f"{p['lacquer_threads'] if p['lacquer_threads'] is not None else 'n/a (no lq_set_thread_count)'}\n")
    head = "| work | Lacquer ns/elem | Mitsuba ns/elem | ratio (min) | ratio (median) | max rel. diff |"
    sep = "|---|---:|---:|---:|---:|---:|"
    if one_core:
        head += " Lacquer speed-up vs 1 core | Mitsuba speed-up vs 1 core |"
        sep += "---:|---:|"
    print(head)
    print(sep)
    base = {(r["case"], r["op"]): r for r in one_core["rows"]} if one_core else {}
    for r in p["rows"]:
        m_min, m_med = per(r["mitsuba_ns"])
        layouts = [("", "lacquer_ns", "check")]
        if "lacquer_soa_ns" in r:
            layouts.append((" [SoA]", "lacquer_soa_ns", "check_soa"))
        for suffix, key, ck in layouts:
            l_min, l_med = per(r[key])
            line = (f"| {r['case']}: {r['op']}{suffix} | {l_min:.1f} | {m_min:.1f} | {l_min / m_min:.2f}× "
                    f"| {l_med / m_med:.2f}× | {fmt_check(r[ck])} |")
            if one_core:
                b = base[(r["case"], r["op"])]
                line += f" {min(b[key]) / min(r[key]):.2f}× | {min(b['mitsuba_ns']) / min(r['mitsuba_ns']):.2f}× |"
            print(line)
    # Lambert against the memory floor.
    f_min, f_med = per(p["memory_floor_ns"])
    lam = next(r for r in p["rows"] if r["case"].startswith("lambert") and r["op"] == "eval")
    print(f"\nMemory floor (numpy `np.add(wi, wo, out=out)`: reads 6 and writes 3 floats per element, "
          f"1 thread): {f_min:.2f} ns/elem (median {f_med:.2f}).\n")
    print("| lambert eval | ns/elem (min) | × memory floor (min) | × memory floor (median) |")
    print("|---|---:|---:|---:|")
    for label, key in (("Lacquer lambert", "lacquer_ns"), ("Lacquer lambert [SoA]", "lacquer_soa_ns"),
                       ("Mitsuba diffuse", "mitsuba_ns")):
        if key in lam:
            mn, md = per(lam[key])
            print(f"| {label} | {mn:.2f} | {mn / f_min:.2f}× | {md / f_med:.2f}× |")


def main():
    global PAUSE_S
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--n", type=int, default=1_000_000, help="direction pairs (default 1e6)")
    ap.add_argument("--reps", type=int, default=7, help="timed repetitions per call (default 7)")
    ap.add_argument("--quick", action="store_true", help="CI smoke run: n = 1e5, 3 repetitions")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--json", type=pathlib.Path, help="write every timing and the set-up to this file")
    ap.add_argument("--pause", type=float, default=PAUSE_S,
                    help=f"seconds between two timed calls, for idle worker pools to sleep (default {PAUSE_S})")
    args = ap.parse_args()
    PAUSE_S = args.pause
    if args.quick:
        args.n, args.reps = 100_000, 3

    import numpy as np
    import drjit as dr
    import mitsuba as mi
    mi.set_variant("llvm_ad_rgb")
    lq = Lacquer(os.environ["LACQUER_LIBRARY"])

    machine = machine_info()
    cpus = machine["allowed_cpus"]
    inp = make_inputs(np, args.n, args.seed)
    versions = {
        "lacquer": lq.version, "lacquer_abi": lq.abi, "library": os.environ["LACQUER_LIBRARY"],
        "library_source": os.environ.get("LACQUER_LIBRARY_SOURCE", "unknown"),
        "lacquer_soa_entry_points": lq.has_soa, "lq_set_thread_count": lq.has_thread_count,
        "mitsuba": mi.__version__, "drjit": dr.__version__, "variant": mi.variant(),
        "llvm": ".".join(map(str, dr.detail.llvm_version())), "libllvm": os.environ.get("DRJIT_LIBLLVM_PATH"),
        "numpy": np.__version__, "python": platform.python_version(), "git": git_describe(),
    }
    log(f"n = {args.n}, {args.reps} repetitions; {machine['cpu']}, {len(cpus)} cpus; "
        f"Lacquer {lq.version} (SoA: {lq.has_soa}, lq_set_thread_count: {lq.has_thread_count})")

    one = run_pass(np, dr, mi, lq, inp, args.reps, "One core (pinned)", {cpus[0]}, 1, 1)
    allc = run_pass(np, dr, mi, lq, inp, args.reps, "All cores", set(cpus), len(cpus), 0)
    set_process_affinity(set(cpus))

    print(f"## Lacquer vs Mitsuba 3 built-in BSDFs: n = {args.n} direction pairs, float32, "
          f"{args.reps} repetitions\n")
    print(f"Machine: {machine['cpu']}, {machine['logical_cpus']} logical CPUs ({', '.join(machine['simd'])}), "
          f"{machine['system']}; load average at start {machine['load_average_start'][0]:.2f}, "
          f"after {allc['load_average_after'][0]:.2f}.  ")
    print(f"Versions: Lacquer {lq.version} (ABI {lq.abi}; tree at git {versions['git']}, library "
          f"{versions['library_source']}; SoA entry points: "
          f"{'yes' if lq.has_soa else 'no'}, lq_set_thread_count: {'yes' if lq.has_thread_count else 'no'}), "
          f"Mitsuba {mi.__version__} `{mi.variant()}`, Dr.Jit {dr.__version__} (LLVM {versions['llvm']}), "
          f"numpy {np.__version__}, Python {versions['python']}.  ")
    print("Command: `" + " ".join(["python3 bench/vs_mitsuba.py", *sys.argv[1:]]) + "`. "
          "ratio = Lacquer time / Mitsuba time (> 1: Lacquer slower); min = ratio of the fastest runs, "
          "median = ratio of the median runs. max rel. diff: Lacquer vs Mitsuba on the same inputs "
          "(eval·cos, pdf; sample: Lacquer's weight and pdf vs Mitsuba's at Lacquer's direction); "
          "— = not the same BRDF (cost of comparable work).")
    print_pass(one, args.n)
    print_pass(allc, args.n, one_core=one)

    if args.json:
        args.json.write_text(json.dumps({"n": args.n, "reps": args.reps, "seed": args.seed, "machine": machine,
                                         "versions": versions, "passes": [one, allc]}, indent=1))
        log(f"wrote {args.json}")


def git_describe():
    try:
        rev = subprocess.run(["git", "-C", str(ROOT), "rev-parse", "--short", "HEAD"], capture_output=True,
                             text=True, check=True).stdout.strip()
        dirty = subprocess.run(["git", "-C", str(ROOT), "status", "--porcelain", "--untracked-files=no"],
                               capture_output=True, text=True).stdout.strip()
        return rev + ("+dirty" if dirty else "")
    except (OSError, subprocess.CalledProcessError):
        return "unknown"


if __name__ == "__main__":
    if os.environ.get(CHILD_MARK) != "1":
        bootstrap()
    main()
