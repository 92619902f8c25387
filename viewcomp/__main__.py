"""`python -m viewcomp ...` is the same as the `viewcomp` command."""

from viewcomp.cli import main

raise SystemExit(main())
