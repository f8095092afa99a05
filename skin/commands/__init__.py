"""The subcommands of ``skin``: one module each, with ``add_parser(sub)`` and ``main(args)``."""
