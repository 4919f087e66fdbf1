"""`python -m hil emulate ...`: the hil commands without the rest of featherstar."""
import sys

from hil.cli import main

sys.exit(main())
