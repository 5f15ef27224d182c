"""``python -m fakeack.cli`` runs the command line (as ``python -m fakeack`` does)."""

from . import main

raise SystemExit(main())
