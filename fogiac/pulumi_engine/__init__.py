"""fogiac's one Pulumi engine, for every cloud whose resources Pulumi makes.

A cloud's target hands it a :class:`~.project.Project` (the Pulumi project, the layer stacks in the
order they are created, the stack config its provider reads, such as ``aws:region``) and the
program of each layer; nothing here knows which cloud that is. The same programs reach:

::

    project.py     what a cloud feeds the engine: its Project, and the program of each layer
    workspace.py   the pinned Pulumi CLI, the file backend in the stack's folder, the passphrase
    engine.py      up, destroy, refresh and preview of the layers through the Automation API,
                   or under Pulumi's mocks where the cloud's API answers in-process (a test cloud)
    events.py      Pulumi engine events as the lifecycle's neutral progress
    offline.py     the offline preview: the programs under mocks, every declared resource recorded
    terraform.py   a declared plan as Terraform plan JSON, for a provider bridged from Terraform

``pulumi`` is imported inside the functions that need it, so importing this package costs nothing.
Only this package and the targets that use it import ``pulumi`` (``tests/test_layering.py``).
"""
