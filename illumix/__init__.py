"""The ``illumix`` command line: the one place that wires retarget, store, renderer_jobs and service."""
