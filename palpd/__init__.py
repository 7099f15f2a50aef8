"""palpd: a robot palpation daemon (Phantom Premium 1.5A + ATI Nano17) that finds stiff lumps in soft tissue.

`palpd.simulate_scan(scene, strategy=...)` runs a scan from a script; `palpd.client.Client` talks to a daemon.
"""

__version__ = "0.1.0"
__all__ = ["__version__", "simulate_scan"]


def __getattr__(name: str):
    # Lazy: `import palpd` (every command line starts with it) must not pay for numpy, scipy and friends.
    if name == "simulate_scan":
        from palpd.embedded import simulate_scan

        return simulate_scan
    raise AttributeError(f"module 'palpd' has no attribute {name!r}")
