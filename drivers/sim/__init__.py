"""The simulated bench: a scene's tissue under a simulated Phantom and Nano17.

Production code reaches it only through the backend registry (``sim``).
"""
