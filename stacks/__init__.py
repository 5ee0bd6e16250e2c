"""fogiac's Pulumi programs, one package per cloud (``stacks.aws``), each fed to the one engine.

Kept apart from ``fogiac/`` so that plain ``pulumi preview`` can run in a cloud's folder (its
``Pulumi.yaml`` and ``__main__.py``) and so that only that cloud's target imports its programs.
This top imports nothing: a cloud's package names what its target reads without loading Pulumi.
"""
