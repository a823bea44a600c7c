#!/usr/bin/env python3
"""The wall demo: `python apps/wall_demo.py --out out/wall` (same options as `vishap demo wall`)."""
import sys

from vishap.cli import main

if __name__ == "__main__":
    sys.exit(main(["demo", "wall", *sys.argv[1:]]))
