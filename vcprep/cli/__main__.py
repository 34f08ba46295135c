"""``python -m vcprep.cli``: the same as the ``vcprep`` command."""
from ..cli import main

main()
