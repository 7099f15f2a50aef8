import sys

from palpd.cli import main

sys.exit(main())
