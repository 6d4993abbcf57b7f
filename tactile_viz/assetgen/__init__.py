"""Procedural generator of the 20 bundled test objects (10 known, 10 novel).

Each object is a signed-distance function (:mod:`.sdf`, :mod:`.catalog`) that
:mod:`.build` samples, meshes and normalises to a longest side of 6.
"""
