"""Prints the Mitsuba property table of the `lacquer` plugin (docs/mitsuba.md) from the model
list of the core (`lacquer models --json`, the same data the plugin reads through
lq_model_param), so the documentation cannot drift from the plugin.

    python3 mitsuba-plugin/tools/properties_table.py [path/to/lacquer] > /tmp/table.md

The binary defaults to $LACQUER_BIN, then target/release/lacquer.
"""

import json
import os
import pathlib
import subprocess
import sys

REPO = pathlib.Path(__file__).resolve().parents[2]
TAGS = {"scalar": "`<float>`", "integer": "`<integer>`", "color": "`<rgb>` / `<float>`", "bool": "`<boolean>`",
        "choice": "`<string>`", "json": "`<string>` (JSON)", "text": "`<string>`"}


def kind_of(p):
    k = p["kind"]
    return ("choice", k["choice"]) if isinstance(k, dict) else (k.lower(), None)


def fmt(x):
    return f"{x:g}" if isinstance(x, (int, float)) and not isinstance(x, bool) else json.dumps(x)


def main():
    binary = sys.argv[1] if len(sys.argv) > 1 else os.environ.get("LACQUER_BIN", str(REPO / "target/release/lacquer"))
    models = json.loads(subprocess.run([binary, "models", "--json"], check=True, capture_output=True, text=True).stdout)
    for m in models:
        print(f"#### `{m['name']}`\n\n{m['summary']}\n")
        print("| property | Mitsuba type | default | range | unit | traverse | meaning |")
        print("|---|---|---|---|---|---|---|")
        for p in m["params"]:
            kind, choices = kind_of(p)
            if kind == "choice":
                rng = ", ".join(f"`{c}`" for c in choices)
            elif kind in ("scalar", "integer", "color"):
                rng = f"[{fmt(p['min'])}, {fmt(p['max'])}]"
            else:
                rng = ""
            trav = "yes" if kind in ("scalar", "integer", "color") else ""
            doc = p["doc"].replace("|", "\\|")
            print(f"| `{p['name']}` | {TAGS.get(kind, kind)} | {fmt(p['default'])} | {rng} | {p['unit']} | {trav} | {doc} |")
        print()


if __name__ == "__main__":
    main()
