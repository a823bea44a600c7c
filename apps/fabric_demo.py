#!/usr/bin/env python3
"""The fabric demo: `python apps/fabric_demo.py --out out/fabric` (same options as `vishap demo fabric`)."""
import sys

from vishap.cli import main

if __name__ == "__main__":
    sys.exit(main(["demo", "fabric", *sys.argv[1:]]))
