import sys

from jaxcds.cli import main

sys.exit(main())
