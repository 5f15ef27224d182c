"""Data files shipped with fakeack (``example.toml``: the paper's system, for ``fakeack analyze``)."""
