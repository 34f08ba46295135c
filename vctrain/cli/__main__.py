"""``python -m vctrain.cli`` (and ``torchrun -m vctrain.cli``): the same as the ``vctrain`` command."""
from ..cli import main

main()
