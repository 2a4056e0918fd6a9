"""catadioptric: setup files, the command line, design and reports.

The only package of the distribution that reads or writes files, prints or plots.
"""

__version__ = "0.1.0"
