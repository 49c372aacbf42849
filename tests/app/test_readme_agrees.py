"""Issue 45, point 7: the README's calibration example takes the mounts the wizard asks for."""

import re
from pathlib import Path

from app.wizard.model import RECOMMENDED_METHOD
from pito_core.calibration import completing_mount


def test_the_readme_example_has_the_wizards_second_mount():
    text = (Path(__file__).parents[2] / "README.md").read_text()
    sims = re.findall(r"pito simulate --protocol calibration --flange (\w+) --connected-face (\d)(?: --faces ([\d,]+))?",
                      text)
    cal = re.search(r"pito calibrate ((?:\S+\.h5 )+)--method (\w+)", text)
    assert cal and cal.group(2) == RECOMMENDED_METHOD
    first = sims[0]
    extra = completing_mount(RECOMMENDED_METHOD, first[0], int(first[1]))
    assert extra is not None  # the face flange alone leaves face 6 and the net load unmeasured
    assert (extra.flange, str(extra.connected_face), ",".join(map(str, extra.faces))) in sims
    assert len(cal.group(1).split()) == 2  # both sessions in the fit
