"""``python -m lacquer_mitsuba install | uninstall | info``: link the native plugins into
Mitsuba's plugin folder (so scenes find ``lacquer`` without ``register()``), remove the links,
or print what the plugins were built for."""

import json
import sys

from . import LacquerError, build_info, install, mitsuba_plugin_dir, uninstall


def main(argv=None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    cmd = argv[0] if argv else "info"
    try:
        if cmd == "install":
            for p in install():
                print(f"linked {p}")
        elif cmd == "uninstall":
            for p in uninstall():
                print(f"removed {p}")
        elif cmd == "info":
            print(json.dumps({"build": build_info(), "mitsuba_plugin_dir": mitsuba_plugin_dir()}, indent=2))
        else:
            print(__doc__, file=sys.stderr)
            return 2
    except LacquerError as e:
        print(f"lacquer_mitsuba: {e}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
