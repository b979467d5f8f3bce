"""The hard set with correlated marker noise: named cover sessions, the noise carried, no cached key moved."""
from horsemocap.virtuallab.covers import COVER_SESSIONS, HARD_NOISE, adapt_scene, cover_key
from horsemocap.virtuallab.hard import HARD_SESSIONS, plan
from horsemocap.virtuallab.noise import MarkerNoise

#: Cache keys read on main (4e7c4ff) before the noisy hard sessions were added, one per family of sessions, and
#: the new sessions' own keys (their renders in the cache).
KEYS = {"four_canter": "a50421cfa124", "three_rising_trot": "616b54a561d8", "spread4_canter": "d9667430fd6d",
        "spread5_rising_trot_f": "e0c30cb2a424", "leg4_walk": "04e59359a427", "leg_canter": "d86619246dd2",
        "rein_sitting_trot": "5a160f6ef11e", "hand_canter": "d6ebe4aac090",
        "noisy_canter720_toedin_60": "99989c13f17f", "noisy_sitting720_toedin_100_occluded_border": "f9a7045e876d"}


def test_every_hard_session_has_a_noisy_twin_with_the_herds_noise():
    assert HARD_NOISE == MarkerNoise(sigma_px=0.1, rho=0.8, bias_px=0.05)
    for name, base in HARD_SESSIONS.items():
        sc = COVER_SESSIONS[f"noisy_{name}"]
        assert sc.base == base
        assert sc.marker_noise == HARD_NOISE
        assert (sc.extra_markers, sc.covers, sc.drop_markers) == ((), (), ())
        assert sc.to_dict()["marker_noise"]["sigma_px"] == 0.1


def test_the_noise_reaches_the_scene_at_the_sessions_frame_rate():
    sc = COVER_SESSIONS["noisy_sitting640_stirrup_30"]
    scene = plan(sc.base, adapt_scene(sc))["scene"]
    assert scene.marker_noise == MarkerNoise(0.1, 0.8, 0.05, frame_rate_hz=30.0)
    assert plan(sc.base)["scene"].marker_noise is None          # the hard session itself stays without


def test_existing_keys_unchanged_and_new_keys_pinned():
    assert {n: cover_key(COVER_SESSIONS[n]) for n in KEYS} == KEYS
