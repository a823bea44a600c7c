import sys

from vishap.cli import main

sys.exit(main())
