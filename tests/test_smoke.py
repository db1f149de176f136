import meshbits


def test_release_build():
    assert meshbits._core.BUILD_PROFILE == "release"
