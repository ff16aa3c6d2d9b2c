"""Text conditioning: no text, a dropped text and an empty text are one thing; words reach the
U-Net's bottleneck only through its cross-attention, which starts at zero."""
import numpy as np
import torch

from engine.models.conditioning import Conditioning
from engine.models.text import TextEncoder
from engine.models.unet import TemporalUNet, UNetConfig
from engine.text import HASH_BUCKETS, TEXT_TOKENS, VOCAB_SIZE, tokenize, with_unknown_words, word_id
from tests.engine.fixtures import fake_conditioning
from tests.engine.models.test_unet import _randomize_zero_inits

torch.set_num_threads(1)


def test_tokens_are_fixed_words_or_stable_hash_buckets():
    t = tokenize("Two people CARRY the box, slowly!")
    assert t["text_mask"].sum() == 6 and t["text_ids"].shape == (TEXT_TOKENS,)
    assert t["text_ids"][1] == word_id("people") > HASH_BUCKETS and t["text_ids"][6:].sum() == 0
    odd = word_id("zyzzyva")
    assert 1 <= odd <= HASH_BUCKETS and odd == word_id("zyzzyva") and word_id("box") < VOCAB_SIZE
    assert tokenize("")["text_mask"].sum() == 0
    assert tokenize(" ".join(["walk"] * 100))["text_mask"].sum() == TEXT_TOKENS
    swapped = with_unknown_words(t, 1.0, np.random.default_rng(0))
    assert np.all(swapped["text_ids"][:6] <= HASH_BUCKETS) and np.array_equal(swapped["text_mask"], t["text_mask"])


def _text_conditioning(texts):
    enc = TextEncoder()
    tokens = [tokenize(t) for t in texts]
    ids = torch.stack([torch.as_tensor(t["text_ids"]) for t in tokens])
    mask = torch.stack([torch.as_tensor(t["text_mask"]) for t in tokens])
    cond = fake_conditioning(len(texts), 30)
    cond.text, cond.text_mask = enc(ids, mask), mask
    return cond


def test_no_text_dropped_text_and_empty_text_are_the_same_and_words_change_the_output():
    net = _randomize_zero_inits(TemporalUNet(UNetConfig(channels=(16, 24, 32, 32), embed_dim=32, heads=2, text_dim=64)))
    z, t = torch.randn(3, 30, 3, 32), torch.rand(3)
    cond = _text_conditioning(["two people carry the box", "", "a pair dance salsa quickly"])
    with_words = net(z, t, cond)
    no_text = net(z, t, Conditioning(cond.residual, cond.temporal_bias, cond.embed))
    dropped = net(z, t, cond.without_text(torch.tensor([True, True, True])))
    assert torch.allclose(no_text, dropped, atol=1e-6)
    assert torch.allclose(with_words[1], no_text[1], atol=1e-6)                # an empty text is no text
    assert not torch.allclose(with_words[0], no_text[0], atol=1e-4)
    other = _text_conditioning(["two people carry the box", "", "two friends shake hands"])
    other.residual, other.temporal_bias, other.embed = cond.residual, cond.temporal_bias, cond.embed
    assert not torch.allclose(net(z, t, other)[2], with_words[2], atol=1e-4)  # other words, other motion
    everything_dropped = net(z, t, cond.dropped(torch.tensor([True, True, True])))
    assert torch.allclose(everything_dropped, net(z, t, None), atol=1e-6)      # CFG's unconditional pass


def test_the_text_layers_start_at_zero():
    plain = TemporalUNet(UNetConfig(channels=(16, 24, 32, 32), embed_dim=32, heads=2))
    reading = TemporalUNet(UNetConfig(channels=(16, 24, 32, 32), embed_dim=32, heads=2, text_dim=64))
    missing = reading.load_state_dict(plain.state_dict(), strict=False).missing_keys
    assert missing and all(k.startswith(("text_attn.", "text_embed.")) for k in missing)
    z, t = torch.randn(2, 30, 3, 32), torch.rand(2)
    cond = _text_conditioning(["two people carry the box", "they shake hands"])
    assert torch.equal(reading(z, t, cond), plain(z, t, cond))
