"""``fsreg-ctl``'s text for how a WM entry is held: where each word came from (WM origin or LTM) and its strength."""

from fsreg_ros.tools.ctl_show import held_text, show_describe


def test_held_text_names_the_origin_and_the_strength():
    assert held_text(None, None) == ""
    assert held_text({"cause": "speaker", "turn": None}, {"age": 0, "episodes": 1, "activation": None}) == (
        " [speaker; age 0, 1 episode]")
    assert held_text({"cause": "rr", "turn": 3}, {"age": 2, "episodes": 3, "activation": -0.4567}) == (
        " [rr turn 3; age 2, 3 episodes, activation -0.46]")
    assert held_text(None, {"age": 0, "episodes": 1, "activation": "inf"}) == " [age 0, 1 episode, activation inf]"


def test_describe_shows_each_word_from_wm_with_its_origin_and_strength_and_ltm_words_as_such():
    answer = {"text": "the woman with glasses", "description": ["glasses", "female"], "sources": ["wm", "ltm"],
              "origins": [{"cause": "human-speech", "turn": 1}, None],
              "strengths": [{"age": 1, "episodes": 2, "activation": None}, None], "distinguishing": True}
    assert show_describe(answer) == (
        '"the woman with glasses" (glasses: wm [human-speech turn 1; age 1, 2 episodes], female: ltm)')
    old = {k: v for k, v in answer.items() if k not in ("origins", "strengths")}  # a reply without them
    assert show_describe(old) == '"the woman with glasses" (glasses: wm, female: ltm)'
