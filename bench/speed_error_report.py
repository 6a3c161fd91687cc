#!/usr/bin/env python3
"""The speed-vs-error report: a table (markdown) and a PNG plot from `lacquer bench --report`.

Usage (from the repository root; sets up its own environment):
    python3 bench/speed_error_report.py            # writes docs/speed-vs-error.md and docs/img/speed-vs-error.png
    python3 bench/speed_error_report.py --quick    # fewer direction pairs (CI smoke)

Every model's f32 batch path (SIMD where the model has a lane kernel) against its f64 reference,
and every approximation the library offers against the exact form it replaces. Error: the
relative error of f·cos θi per RGB channel, with a floor of 1e-3 of the peak value (see
`lacquer::bench::error_stats`); "ns fast" is the f32 batch cost per element (one thread),
"ns reference" the f64 call (models) or the exact form's batch cost (approximations).
"""
import argparse
import json
import os
import platform
import subprocess
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def ensure_env():
    """Re-runs this script inside the test venv with matplotlib installed."""
    if os.environ.get("LACQUER_REPORT_VENV") == "1":
        return
    venv = subprocess.run(["bash", os.path.join(ROOT, "scripts/python-env.sh")], check=True,
                          capture_output=True, text=True).stdout.strip()
    py = os.path.join(venv, "bin", "python")
    if subprocess.run([py, "-c", "import matplotlib"], capture_output=True).returncode != 0:
        subprocess.run([py, "-m", "pip", "install", "-q", "--disable-pip-version-check", "matplotlib==3.11.2"],
                       check=True)
    env = dict(os.environ, LACQUER_REPORT_VENV="1")
    os.execve(py, [py, os.path.abspath(__file__)] + sys.argv[1:], env)


def cpu():
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown CPU"


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true", help="fewer direction pairs (smoke run)")
    ap.add_argument("--out-md", default=os.path.join(ROOT, "docs/speed-vs-error.md"))
    ap.add_argument("--out-png", default=os.path.join(ROOT, "docs/img/speed-vs-error.png"))
    args = ap.parse_args()
    ensure_env()
    binary = os.environ.get("LACQUER_BIN", os.path.join(ROOT, "target/release/lacquer"))
    if not os.path.exists(binary):
        subprocess.run(["cargo", "build", "--release", "-q", "-p", "lacquer-cli"], cwd=ROOT, check=True)
    cmd = [binary, "bench", "--report", "--json"] + (["--quick"] if args.quick else ["--n", "65536"])
    doc = json.loads(subprocess.run(cmd, check=True, capture_output=True, text=True).stdout)
    rows = doc["rows"]

    lines = [
        "# Speed against error",
        "",
        f"Machine: {cpu()}, {os.cpu_count()} cores; SIMD level {doc['simd']}; {doc['n']} random direction pairs.",
        f"Command: `python3 bench/speed_error_report.py` (runs `{' '.join(['lacquer'] + cmd[1:])}`).",
        "",
        "Error: relative error of f·cos θi per RGB channel against the reference, with a floor of",
        "1e-3 of the reference's peak value (values near zero do not dominate). ns fast: the f32 batch",
        "path per element on one thread (SIMD where the model has a lane kernel); ns reference: the f64",
        "scalar call (models) or the exact form's f32 batch cost (approximations). Absolute times move",
        "with the machine's load; read ratios within one run.",
        "",
        "![speed against error](img/speed-vs-error.png)",
        "",
        "| model / approximation | comparison | ns fast | ns reference | max error | RMS error |",
        "|---|---|---|---|---|---|",
    ]
    for r in rows:
        e = r["error"]
        lines.append(f"| {r['what']} | {r['comparison']} | {r['ns_fast']:.1f} | {r['ns_reference']:.1f} | "
                     f"{e['max']:.2e} | {e['rms']:.2e} |")
    lines += [
        "",
        "The analytic paint layering against the position-free Monte Carlo reference is not re-run",
        "here (it takes minutes per configuration): its error and cost are in",
        "[paint-validation.md](paint-validation.md) (0.2–3 % mean error at ~3×10⁴ times the speed).",
        "",
    ]
    with open(args.out_md, "w") as f:
        f.write("\n".join(lines))

    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(9, 6), dpi=110)
    for r in rows:
        err = max(r["error"]["max"], 1e-9)
        is_model = "vs f64 reference" in r["comparison"]
        ax.scatter(r["ns_fast"], err, marker="o" if is_model else "s", color="tab:blue" if is_model else "tab:red")
        ax.annotate(r["what"][:28], (r["ns_fast"], err), fontsize=6, xytext=(3, 2), textcoords="offset points")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("ns per evaluation (f32 batch, one thread)")
    ax.set_ylabel("max relative error of f·cos θ vs reference")
    ax.set_title("Lacquer: speed against error (blue: f32 vs f64 per model; red: approximations)")
    ax.grid(True, which="both", alpha=0.3)
    fig.tight_layout()
    fig.savefig(args.out_png)
    print(f"wrote {args.out_md} and {args.out_png}")


if __name__ == "__main__":
    main()
