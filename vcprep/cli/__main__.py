"""``python -m vcprep.cli``: the same as the ``vcprep`` command."""
from . import main

main()
