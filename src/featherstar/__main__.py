"""`python -m featherstar ...` is the `featherstar` command."""
import sys

from featherstar.app import main

sys.exit(main())
