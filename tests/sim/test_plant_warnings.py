"""DART's zero-mass warnings: silenced for the massless frame links only, never for a real body."""
from hybrid_dyn.sim.plant import load_skeleton, massless_frame_links


def test_massless_frame_links_are_the_welded_frames(panda):
    assert massless_frame_links(panda.urdf_xml) == ["panda_link8", "panda_hand_tcp"]


def test_frame_links_do_not_warn_but_a_massless_moving_link_does(panda, capfd):
    load_skeleton(panda.urdf_xml)
    assert "zero mass" not in capfd.readouterr().err
    # Give a moving link zero mass: that is a modelling error, and DART's warning must get through.
    xml = panda.urdf_xml
    i = xml.find('<link name="panda_link3"')
    j = xml.find("<mass", i)
    k = xml.find("/>", j)
    load_skeleton(xml[:j] + '<mass value="0"' + xml[k:])
    err = capfd.readouterr().err
    assert "zero mass" in err and "panda_link3" in err and "panda_link8" not in err
