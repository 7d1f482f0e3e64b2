"""Wire-level simulators of the bench's devices, sharing one simulated world.

Each simulator is split the lewis way: a device model (physics, an injected clock, no bytes), a protocol
front (bytes in, bytes out) and a back door for faults that the wire protocol cannot reach.
"""
