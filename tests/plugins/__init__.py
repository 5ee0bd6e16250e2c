"""Plug-ins defined only in the tests, each in its own folder, registered through entry points
(:mod:`tests.plugins.install` writes the dist-info a package would install)."""
