"""The core: ``solve``, ``Solution``, the registry and base classes, events, and the segment driver
that the adapters to external libraries share."""
