"""What the entry points do: `simulate.py` (`cli.simulate`). The top of the dependency order:
it may read any module, none reads it."""
