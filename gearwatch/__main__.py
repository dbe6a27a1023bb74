import sys

from gearwatch.cli import main

sys.exit(main())
