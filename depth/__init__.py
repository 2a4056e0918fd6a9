"""depth: depth from aspect ratio (DDAR) and line slope (DDS) in XSlit images.

XSlit projection, the paper's DDAR/DDS equations, prior-based solvers, image
measurement and depth estimators. This package never reads or writes files and
never prints.
"""
