"""The ``lasercal`` command line: one table of subcommands (``main.py``) and thin handlers that parse
arguments, call one library function and print."""
