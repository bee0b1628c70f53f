import sys

from genr8_dist.cli import main

sys.exit(main())
