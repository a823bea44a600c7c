#!/usr/bin/env python3
"""The button demo: `python apps/button_demo.py --out out/button` (same options as `vishap demo button`)."""
import sys

from vishap.cli import main

if __name__ == "__main__":
    sys.exit(main(["demo", "button", *sys.argv[1:]]))
