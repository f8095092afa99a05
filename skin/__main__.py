"""``python -m skin``: the same as the ``skin`` command."""

from skin.cli import main

raise SystemExit(main())
