import sys

from omni_micro_cli.cli import main

sys.exit(main())
