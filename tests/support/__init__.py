"""Shared helpers for fogiac's tests (not part of the installed package).

- :mod:`tests.support.netns`: throwaway network namespaces, veth links, processes inside them,
  and cleanup that runs even when a test fails.
"""
