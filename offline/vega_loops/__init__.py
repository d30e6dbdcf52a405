"""Frozen-time loops of the flown controller, shared by every offline package.

The bottom layer of the offline side (offline/README.md): the sampled-data loop of plant,
actuator, delay and discrete controller at a frozen flight time, its frequency responses and
stability, the classical margins and the heritage criteria they are judged by (margins), the
dispersed corners of the thesis' uncertainty set, state-space series connection, and the
writing of controller tables (export). It imports only the workspace packages below it.
"""
