"""pyserial protocol handlers of sunbench (``sim://``); registered by :func:`drivers.transport.register_sim_scheme`."""
