"""The answer-encoder registry (service/encoders.py): one entry per format= the request accepts,
shared by GET /sample and POST /batch (issue 34)."""

from __future__ import annotations

from illumix.engine.spec import FORMATS
from illumix.service.encoders import ENCODERS, Encoder, encoder
from illumix.service.encoding import MEDIA


def test_every_format_has_one_encoder_with_its_media_type():
    assert set(ENCODERS) == set(FORMATS)
    for name in FORMATS:
        e = encoder(name)
        assert isinstance(e, Encoder) and e.name == name and e.media_type == MEDIA[name]


def test_only_the_container_formats_take_batches():
    assert {n for n, e in ENCODERS.items() if e.batch} == {"npz", "arrays"}
