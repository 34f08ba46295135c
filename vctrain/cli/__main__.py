"""``python -m vctrain.cli`` (and ``torchrun -m vctrain.cli``): the same as the ``vctrain`` command."""
from . import main

main()
