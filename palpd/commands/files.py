"""palpd files [NAME]: the files palpd ships for installers (default config, systemd unit, udev rule, calibration).

    palpd files systemd/palpd.service | sudo tee /etc/systemd/system/palpd.service
"""
from __future__ import annotations

import sys


def add_parser(subparsers):
    files = subparsers.add_parser("files", help="list the shipped files, or print one (e.g. systemd/palpd.service)")
    files.add_argument("name", nargs="?", metavar="NAME", help="a shipped file to print; default: list them")
    files.add_argument("--path", action="store_true", help="print where the file is instead of its content")
    return files


def run(args) -> int:
    from palpd.shipped import FILES, shipped_file

    if args.name is None:
        for name in FILES:
            print(f"{name}  {shipped_file(name)}" if args.path else name)
        return 0
    path = shipped_file(args.name)
    if args.path:
        print(path)
    else:
        sys.stdout.write(path.read_text())
    return 0
