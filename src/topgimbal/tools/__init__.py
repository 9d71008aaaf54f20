"""Tools built on the library: docs generator, demo, recorder."""
