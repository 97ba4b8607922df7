"""The ``gearsim`` command: parse arguments, call the library."""
