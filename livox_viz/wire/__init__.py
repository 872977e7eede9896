"""Stage 6a, RflySim's wire: frames as RflySim publishes them, sent and received.

Takes scan frames (or datagrams and shared memory) and gives RflySim's payloads,
UDP datagrams, shared-memory blocks and sensor requests
(:mod:`~livox_viz.wire.rflysim`, pure functions), the sockets and shared-memory
links around them (:mod:`~livox_viz.wire.transport`), and what a client receives
(:class:`~livox_viz.wire.received.ReceivedFrame`).
"""
