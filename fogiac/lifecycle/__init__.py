"""The lifecycle: ``up``, ``down`` and ``status`` written once, asking a target driver what differs.

::

    driver.py    the Target protocol the lifecycle asks, its records, and the features a target declares
    sequence.py  up, down, status
    edge.py      the robot's side on this machine, and provision-and-connect, where every up ends
    events.py    provider-neutral progress events and their timers
    report.py    the lifecycle's part of ``fogiac status`` in a terminal

The lifecycle imports no target: the CLI looks the target up in its registry and hands it in.
"""
