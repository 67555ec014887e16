"""The factorisations to test (laminid_cli.modal.FACTORIZERS): CHOLMOD only where cvxopt is
installed (the ``fast`` extra; ``make setup`` installs it, and falls back to the banded
Cholesky alone where cvxopt cannot be installed)."""

import pytest

from laminid_cli.modal import cholmod_available

HAVE_CHOLMOD = cholmod_available()
NEEDS_CHOLMOD = pytest.mark.skipif(not HAVE_CHOLMOD, reason="cvxopt (CHOLMOD) is not installed")
#: parametrisation over both factorisations
KINDS = [pytest.param("cholmod", marks=NEEDS_CHOLMOD), "banded"]
