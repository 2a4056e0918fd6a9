"""xslit_fit: virtual slits of reflected ray bundles.

Plücker and GLC algebra, two-slit fits, GLC type classification, the XSlit frame
and local fit maps. This package never reads or writes files and never prints.
"""
