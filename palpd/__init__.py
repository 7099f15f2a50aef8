"""palpd: a robot palpation daemon (Phantom Premium 1.5A + ATI Nano17) that finds stiff lumps in soft tissue."""

__version__ = "0.1.0"
