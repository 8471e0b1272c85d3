"""NMEA 0183: the sentences the simulated receiver writes (write), and reading what real receivers write:
sentences into records (read), satellite numbers into systems and signals (systems), a stream into
epochs (epochs)."""

from sim.nmea.read import parse
from sim.nmea.write import KNOT_MPS, checksum, fix_sentences, gga, gsa, gsv, rmc, sentence

__all__ = ["KNOT_MPS", "checksum", "fix_sentences", "gga", "gsa", "gsv", "parse", "rmc", "sentence"]
