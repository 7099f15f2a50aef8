"""palpd's shipped defaults (installed as the package data palpd.share): palpd.toml, scenes/, calibration/.

The directory stays config/ in the repository; setup.py maps it into the wheel. Read it through palpd.shipped.
"""
