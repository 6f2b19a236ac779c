"""The choices that are types (renderer.integrators): their members are the JSON strings the API and
the stored sessions carry, and every registry keyed by them covers them all."""

from __future__ import annotations

import json

from renderer.integrators import Denoiser, Integrator, ToneMap, values


def test_members_are_their_json_strings():
    assert values(Integrator) == ("whitted", "path")
    assert json.dumps([Integrator.PATH, ToneMap.ACES, Denoiser.OIDN]) == '["path", "aces", "oidn"]'
    assert Integrator("path") is Integrator.PATH and f"{Integrator.PATH}" == "path"


def test_the_settings_offer_exactly_the_members():
    from renderer.config.settings import setting

    for name, choices in (("integrator", Integrator), ("tone_map", ToneMap), ("denoise", Denoiser)):
        assert setting(name).choices == values(choices), name


def test_every_tone_map_has_its_operator_and_every_denoiser_its_bytes():
    from renderer.image.denoise import BYTES_PER_PIXEL, denoise_nbytes
    from renderer.image.tonemap import OPERATORS

    assert set(OPERATORS) == set(ToneMap)
    assert set(BYTES_PER_PIXEL) == set(Denoiser) - {Denoiser.OFF}
    assert denoise_nbytes("oidn", 2, 3) == 6 * BYTES_PER_PIXEL[Denoiser.OIDN] and denoise_nbytes("off", 2, 3) == 0


def test_a_method_says_its_integrators_as_members():
    from renderer.config.methods import METHODS, integrator_methods

    assert METHODS["bih"].capabilities.integrators == (Integrator.WHITTED, Integrator.PATH)
    assert METHODS["hre"].capabilities.integrators == (Integrator.WHITTED,)
    assert "hre" not in integrator_methods(Integrator.PATH) and "bih" in integrator_methods("path")
