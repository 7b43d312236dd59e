"""Reading photos: formats, depths, channels, and the JPEG chroma-subsampling probe."""

import cv2
import numpy as np
import pytest

from lasercal.vision.errors import ImageReadError
from lasercal.vision.images import chroma_subsampled, full_scale, read_image, to_gray


def test_read_keeps_depth_and_drops_alpha(tmp_path):
    rgba = np.zeros((8, 9, 4), np.uint8)
    rgba[..., 2], rgba[..., 3] = 200, 50
    cv2.imwrite(str(tmp_path / "a.png"), rgba)
    img = read_image(tmp_path / "a.png")
    assert img.shape == (8, 9, 3) and img[0, 0, 2] == 200
    deep = np.full((5, 6, 3), 40000, np.uint16)
    cv2.imwrite(str(tmp_path / "d.png"), deep)
    d = read_image(tmp_path / "d.png")
    assert d.dtype == np.uint16 and full_scale(d) == 65535 and to_gray(d).dtype == np.uint8
    cv2.imwrite(str(tmp_path / "g.png"), np.zeros((4, 4), np.uint8))
    assert read_image(tmp_path / "g.png").shape == (4, 4)


def test_unreadable_files_name_the_file(tmp_path):
    with pytest.raises(ImageReadError, match=r"nope\.jpg: no such file"):
        read_image(tmp_path / "nope.jpg")
    (tmp_path / "empty.jpg").write_bytes(b"")
    with pytest.raises(ImageReadError, match=r"empty\.jpg: not an image"):
        read_image(tmp_path / "empty.jpg")
    (tmp_path / "cut.jpg").write_bytes(b"\xff\xd8\xff\xe0\x00\x10JFIF")
    with pytest.raises(ImageReadError, match=r"cut\.jpg: not an image"):
        read_image(tmp_path / "cut.jpg")


def test_chroma_subsampling_probe(tmp_path):
    img = (np.random.default_rng(0).random((32, 32, 3)) * 255).astype(np.uint8)
    cv2.imwrite(str(tmp_path / "420.jpg"), img)
    cv2.imwrite(
        str(tmp_path / "444.jpg"),
        img,
        [cv2.IMWRITE_JPEG_SAMPLING_FACTOR, cv2.IMWRITE_JPEG_SAMPLING_FACTOR_444],
    )
    cv2.imwrite(str(tmp_path / "grey.jpg"), img[..., 0])
    cv2.imwrite(str(tmp_path / "x.png"), img)
    assert chroma_subsampled(tmp_path / "420.jpg")
    assert not any(chroma_subsampled(tmp_path / n) for n in ("444.jpg", "grey.jpg", "x.png", "missing.jpg"))


def test_a_cut_png_is_one_line_of_lasercal_not_the_codecs(tmp_path, capfd):
    # Issue 47 item 11: libpng printed "libpng error: PNG input buffer is incomplete" on fd 2 before
    # lasercal's own line. Now the codec's words are in that line, and nothing else reaches stderr.
    from lasercal.collector.cli.main import main

    img = (np.random.default_rng(1).random((60, 80, 3)) * 255).astype(np.uint8)
    ok, buf = cv2.imencode(".png", img)
    (tmp_path / "cut.png").write_bytes(buf.tobytes()[: buf.size // 2])
    damaged = bytearray(buf.tobytes())
    damaged[100] ^= 0xFF  # inside the image data: a CRC error
    (tmp_path / "crc.png").write_bytes(bytes(damaged))
    why = {"cut.png": "the PNG is cut short", "crc.png": r"cannot decode the photo \(IDAT: CRC error\)"}
    for name in ("cut.png", "crc.png"):
        with pytest.raises(ImageReadError, match=rf"{name}: {why[name]}"):
            read_image(tmp_path / name)
        assert capfd.readouterr().err == ""
    assert main(["spots", str(tmp_path / "cut.png")]) == 2
    err = capfd.readouterr().err.splitlines()
    assert len(err) == 1 and err[0].startswith("lasercal: error: 1 of 1 photos not measured"), err
    assert "cut short" in err[0] and "libpng" not in err[0] and "WARN" not in err[0]
