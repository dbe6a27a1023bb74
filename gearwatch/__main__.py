import sys

from gearwatch.cli.main import main

sys.exit(main())
