"""Three made-up trials in the TUNA XML format, written on demand (no corpus file is kept in the repository).

The real corpus may not be copied here (its licence); these trials are this project's own, small enough
to score by hand.  :func:`write_mini` writes them under a directory laid out as the corpus is.
"""

from pathlib import Path

#: Relative path -> XML text.
TRIALS = {
    'furniture/m1.xml': """\
<?xml version="1.0"?>
<TRIAL CARDINALITY="1" CONDITION="-LOC" DOMAIN="furniture" ID="m1" SIMILARITY="similar">
  <DOMAIN>
    <ENTITY ID="1" IMAGE="made-up.gif" TYPE="target">
      <ATTRIBUTE NAME="type" TYPE="literal" VALUE="chair"/>
      <ATTRIBUTE NAME="colour" TYPE="literal" VALUE="red"/>
      <ATTRIBUTE NAME="orientation" TYPE="literal" VALUE="front"/>
      <ATTRIBUTE NAME="size" TYPE="literal" VALUE="large"/>
      <ATTRIBUTE NAME="x-dimension" TYPE="gradable" VALUE="1"/>
    </ENTITY>
    <ENTITY ID="2" IMAGE="made-up.gif" TYPE="distractor">
      <ATTRIBUTE NAME="type" TYPE="literal" VALUE="chair"/>
      <ATTRIBUTE NAME="colour" TYPE="literal" VALUE="blue"/>
      <ATTRIBUTE NAME="orientation" TYPE="literal" VALUE="front"/>
      <ATTRIBUTE NAME="size" TYPE="literal" VALUE="small"/>
      <ATTRIBUTE NAME="x-dimension" TYPE="gradable" VALUE="2"/>
    </ENTITY>
    <ENTITY ID="3" IMAGE="made-up.gif" TYPE="distractor">
      <ATTRIBUTE NAME="type" TYPE="literal" VALUE="chair"/>
      <ATTRIBUTE NAME="colour" TYPE="literal" VALUE="red"/>
      <ATTRIBUTE NAME="orientation" TYPE="literal" VALUE="back"/>
      <ATTRIBUTE NAME="size" TYPE="literal" VALUE="small "/>
      <ATTRIBUTE NAME="x-dimension" TYPE="gradable" VALUE="3"/>
    </ENTITY>
    <ENTITY ID="4" IMAGE="made-up.gif" TYPE="distractor">
      <ATTRIBUTE NAME="type" TYPE="literal" VALUE="desk"/>
      <ATTRIBUTE NAME="colour" TYPE="literal" VALUE="red"/>
      <ATTRIBUTE NAME="orientation" TYPE="literal" VALUE="front"/>
      <ATTRIBUTE NAME="size" TYPE="literal" VALUE="large"/>
      <ATTRIBUTE NAME="x-dimension" TYPE="gradable" VALUE="4"/>
    </ENTITY>
  </DOMAIN>
  <STRING-DESCRIPTION>the red chair facing front</STRING-DESCRIPTION>
  <ATTRIBUTE-SET>
    <ATTRIBUTE ID="a1" NAME="type" VALUE="chair"/>
    <ATTRIBUTE ID="a2" NAME="colour" VALUE="red"/>
    <ATTRIBUTE ID="a3" NAME="orientation" VALUE="front"/>
  </ATTRIBUTE-SET>
</TRIAL>
""",
    'furniture/m2.xml': """\
<?xml version="1.0"?>
<TRIAL CARDINALITY="1" CONDITION="-LOC" DOMAIN="furniture" ID="m2" SIMILARITY="similar">
  <DOMAIN>
    <ENTITY ID="1" IMAGE="made-up.gif" TYPE="distractor">
      <ATTRIBUTE NAME="type" TYPE="literal" VALUE="desk"/>
      <ATTRIBUTE NAME="colour" TYPE="literal" VALUE="grey"/>
      <ATTRIBUTE NAME="orientation" TYPE="literal" VALUE="right"/>
      <ATTRIBUTE NAME="size" TYPE="literal" VALUE="small"/>
    </ENTITY>
    <ENTITY ID="2" IMAGE="made-up.gif" TYPE="target">
      <ATTRIBUTE NAME="type" TYPE="literal" VALUE="desk"/>
      <ATTRIBUTE NAME="colour" TYPE="literal" VALUE="grey"/>
      <ATTRIBUTE NAME="orientation" TYPE="literal" VALUE="left"/>
      <ATTRIBUTE NAME="size" TYPE="literal" VALUE="small"/>
    </ENTITY>
    <ENTITY ID="3" IMAGE="made-up.gif" TYPE="distractor">
      <ATTRIBUTE NAME="type" TYPE="literal" VALUE="sofa"/>
      <ATTRIBUTE NAME="colour" TYPE="literal" VALUE="grey"/>
      <ATTRIBUTE NAME="orientation" TYPE="literal" VALUE="left"/>
      <ATTRIBUTE NAME="size" TYPE="literal" VALUE="small"/>
    </ENTITY>
  </DOMAIN>
  <STRING-DESCRIPTION>the grey desk facing left</STRING-DESCRIPTION>
  <ATTRIBUTE-SET>
    <ATTRIBUTE ID="a1" NAME="type" VALUE="desk"/>
    <ATTRIBUTE ID="a2" NAME="orientation" VALUE="left"/>
    <ATTRIBUTE ID="a3" NAME="colour" VALUE="grey"/>
  </ATTRIBUTE-SET>
</TRIAL>
""",
    'people/m3.xml': """\
<?xml version="1.0"?>
<TRIAL CARDINALITY="1" CONDITION="+LOC" DOMAIN="people" ID="m3" SIMILARITY="similar">
  <DOMAIN>
    <ENTITY ID="1" IMAGE="made-up.gif" TYPE="target">
      <ATTRIBUTE NAME="type" TYPE="literal" VALUE="person"/>
      <ATTRIBUTE NAME="hasBeard" TYPE="boolean" VALUE="1"/>
      <ATTRIBUTE NAME="hasGlasses" TYPE="boolean" VALUE="0"/>
      <ATTRIBUTE NAME="age" TYPE="literal" VALUE="old "/>
      <ATTRIBUTE NAME="x-dimension" TYPE="gradable" VALUE="1"/>
    </ENTITY>
    <ENTITY ID="2" IMAGE="made-up.gif" TYPE="distractor">
      <ATTRIBUTE NAME="type" TYPE="literal" VALUE="person"/>
      <ATTRIBUTE NAME="hasBeard" TYPE="boolean" VALUE="0"/>
      <ATTRIBUTE NAME="hasGlasses" TYPE="boolean" VALUE="1"/>
      <ATTRIBUTE NAME="age" TYPE="literal" VALUE="old "/>
      <ATTRIBUTE NAME="x-dimension" TYPE="gradable" VALUE="2"/>
    </ENTITY>
  </DOMAIN>
  <STRING-DESCRIPTION>the man with a beard on the left</STRING-DESCRIPTION>
  <ATTRIBUTE-SET>
    <ATTRIBUTE ID="a1" NAME="type" VALUE="person"/>
    <ATTRIBUTE ID="a2" NAME="hasBeard" VALUE="1"/>
    <ATTRIBUTE ID="a3" NAME="x-dimension" VALUE="1"/>
  </ATTRIBUTE-SET>
</TRIAL>
""",
}


def write_mini(root: Path) -> Path:
    """Write the made-up trials under ``root`` (``furniture/``, ``people/``) and return ``root``."""
    for name, text in TRIALS.items():
        path = root / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text, encoding="utf-8")
    return root
