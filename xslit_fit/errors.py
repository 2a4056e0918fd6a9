"""xslit_fit errors: the single base error `FitError` of the `xslit_fit` package.

Invalid arguments at the public boundary raise `FitError` with a message naming the argument
and what was expected. A fit that cannot be made (degenerate rays) does not raise: it returns
a falsy `FailedFit` carrying its reason.
"""


class FitError(ValueError):
    """Invalid input to an `xslit_fit` function or class."""
