"""The extended photograph set: several hundred openly licensed photographs.

The first training set (:data:`imgform_rs.training.photos.TRAINING`, 33 photographs)
is kept unchanged as its first part; :data:`EXTENDED`, which ``"raisr"`` and
``"fusion"`` train on, adds to it the photographs of five more Debian packages, and
:data:`EXTENDED_HELD_OUT` holds out six of them (with today's three) as a check on
unseen photographs. ``make training-data`` fetches every package at a pinned version
and :func:`imgform_rs.training.photos.load` checks each file's SHA-256 prefix.

The photographs and their licences, as each package's ``copyright`` file states them
(GCompris: the per-file README beside the photographs, see below):

- GCompris educational activities (Debian ``gcompris-qt-data`` 3.1-2), 214 photos stored
  as WebP inside the activities' Qt resource files (``.rcc``): animals (``erase``,
  ``explore_farm_animals``, ``explore_world_animals``), monuments
  (``explore_monuments``), underwater scenes (``clickgame``), musicians
  (``explore_world_music``) and objects, fish, windmills, dams and solar panels
  (``categorization``). The Debian ``copyright`` file puts them under ``Files: *``
  (GPL-3+); upstream's README in each resource folder names the photographer, the
  Wikimedia Commons source and the licence of every file, and that licence is the one
  in :data:`LICENCES`: public domain (115), CC0-1.0 (63), CC-BY-SA-4.0 (29),
  CC-BY-2.0 (5), CC-BY-3.0 (2); the photographer and source of each of the 36 CC-BY
  and CC-BY-SA ones, as the README gives them, in :data:`ATTRIBUTION`.
- KPhotoAlbum's demo album (Debian ``kphotoalbum`` 5.9.1-1, ``/usr/share/kphotoalbum/
  demo``), 24 photographs of people, pets, beaches and the Grand Canyon by the
  KPhotoAlbum authors; the ``copyright`` file: GPL-2+ for the whole package.
- Tux Paint's templates (Debian ``tuxpaint-data`` 1:0.9.28-sdl2-1), 19 photographs of
  bark, rocks, sea, trees, sheep and a mill machine by Bill Kendrick (AUTHORS.txt);
  ``Files: *``, GPL-2+.
- Palapeli's puzzles (Debian ``palapeli-data`` 4:22.12.3-1), 5 photographs (castle,
  bridge, citrus fruits, honey bee, chameleon); ``Files: *``, GPL-2+.
- Ubuntu Touch 20.04 wallpapers (Debian ``lomiri-wallpapers-20.04`` 20.04.0-2):
  Kleiber (Lukas Baubkus), CC-BY-SA-3.0.
- MATE's nature backgrounds (``mate-backgrounds`` 1.26.0-1, already fetched for raisr):
  Garden, LadyBird and YellowFlower (Charles Barbin), GPL-2+.

Held out: GCompris' toucan and Petra, a windmill of ``categorization``, Tux Paint's
rocks, KPhotoAlbum's skagen and Palapeli's citrus fruits.

Left out: GCompris' ``aulaPalatina`` and ``categorization`` ``screwDriver`` (their
README gives no licence); its paintings (``details``, ``paintings``), cartoons
(``lang``, ``babymatch``) and planet renders (``solar_system``); eight
``categorization`` monuments that show the same buildings as ``explore_monuments``
(Brandenburg Gate, Colosseum, Eiffel Tower, Mount Rushmore, Taj Mahal, Victoria
Memorial, the Great Pyramid and the Great Wall), so that every photograph is counted
once. The other wallpaper packages looked at hold renders, gradients and vector art,
not photographs: ``gnome-backgrounds`` 43.1, ``ukui-wallpapers``, ``sway-backgrounds``,
``xfdesktop4-data``, the ``debian-edu-artwork`` themes, the rest of
``lomiri-wallpapers-20.04`` and of ``plasma-workspace-wallpapers``. Stellarium's
nebula photographs were left out: many of them state no licence.
"""

from __future__ import annotations

from pathlib import PurePosixPath

from imgform_rs.training.photos import HELD_OUT, TRAINING, Photo


def _gcompris(activity: str, path: str, sha256: str) -> Photo:
    """A photograph inside a GCompris activity's resource file, ``path`` under the
    activity's ``resource`` folder."""
    return Photo(
        f"gcompris/{activity}/{PurePosixPath(path).with_suffix('')}",
        f"/gcompris/src/activities/{activity}/resource/{path}",
        sha256,
        rcc=f"gcompris/usr/share/gcompris-qt/rcc/{activity}.rcc",
    )


def _file(package: str, folder: str, stem: str, sha256: str) -> Photo:
    return Photo(f"{package}/{stem}", f"{package}/{folder}/{stem}.jpg", sha256)


#: (activity, path in its ``resource`` folder, SHA-256 prefix, licence from upstream's README).
_GCOMPRIS = [
    ("erase", "alpaca.webp", "ffd29864f09bf743", "CC-BY-SA-4.0"),
    ("erase", "bee.webp", "810de9fea0499e4d", "CC-BY-2.0"),
    ("erase", "butterfly.webp", "e12b50bb4ee6bb36", "CC-BY-SA-4.0"),
    ("erase", "calf.webp", "5957d392349d9016", "CC-BY-SA-4.0"),
    ("erase", "camels.webp", "df4da85790b8a403", "CC-BY-SA-4.0"),
    ("erase", "caterpillar.webp", "1aca9fcc5a0e3e9f", "CC-BY-SA-4.0"),
    ("erase", "chamaeleon.webp", "8a338c7df32949c5", "CC-BY-3.0"),
    ("erase", "cheetah.webp", "b9d85c2e2899036e", "CC-BY-SA-4.0"),
    ("erase", "crab.webp", "822be2d08adc89a7", "CC0-1.0"),
    ("erase", "dolphin.webp", "2847f84c4c9698a9", "CC-BY-SA-4.0"),
    ("erase", "flying_fox.webp", "076622230f0634c0", "CC-BY-SA-4.0"),
    ("erase", "gibbon.webp", "a7b242c4b014e7e3", "CC-BY-3.0"),
    ("erase", "giraffe.webp", "c39106edc785a65b", "public-domain"),
    ("erase", "goat.webp", "acba63337c11582a", "CC-BY-SA-4.0"),
    ("erase", "gorilla.webp", "5ce6131ce966f585", "CC-BY-SA-4.0"),
    ("erase", "gosling.webp", "dab7bc930f6fe4f7", "CC-BY-SA-4.0"),
    ("erase", "heron.webp", "63006dabe8b74b82", "CC-BY-SA-4.0"),
    ("erase", "horse.webp", "15b49393342bf7de", "CC-BY-SA-4.0"),
    ("erase", "kingfisher.webp", "b637658d7e0f8f55", "CC0-1.0"),
    ("erase", "kitten.webp", "c6f3a52585a3d617", "CC-BY-2.0"),
    ("erase", "long_nosed_monkey.webp", "7dcb104852733952", "CC-BY-SA-4.0"),
    ("erase", "macaque.webp", "3a97a3c854c6d93c", "CC-BY-SA-4.0"),
    ("erase", "meerkats.webp", "459198d83393a183", "CC-BY-SA-4.0"),
    ("erase", "northern_harrier.webp", "e2b2f388dc6f92ce", "CC-BY-SA-4.0"),
    ("erase", "nubian_ibex.webp", "5268033ecc366dbc", "CC-BY-SA-4.0"),
    ("erase", "penguin.webp", "1c8be6df0a6ff161", "CC-BY-SA-4.0"),
    ("erase", "pika.webp", "1c8a4014d0793806", "public-domain"),
    ("erase", "red_panda.webp", "ec755f7b9d895303", "CC0-1.0"),
    ("erase", "rhinoceros.webp", "250140eb6d3a0af1", "CC-BY-SA-4.0"),
    ("erase", "spoonbills.webp", "f67d7d04bf3ba227", "CC-BY-SA-4.0"),
    ("erase", "squirrel.webp", "56bdd761a41440bd", "CC-BY-SA-4.0"),
    ("erase", "swans.webp", "5fe69699bf37d702", "CC-BY-SA-4.0"),
    ("erase", "toucan.webp", "977b0ff4277075a4", "CC-BY-SA-4.0"),
    ("explore_monuments", "egypt/bentPyramid.webp", "ca717a088d790a90", "public-domain"),
    ("explore_monuments", "egypt/greatPyramidOfGiza.webp", "f8427c09579493e7", "CC0-1.0"),
    ("explore_monuments", "egypt/meidumPyramid.webp", "694a4eaebc52849a", "public-domain"),
    ("explore_monuments", "egypt/redPyramid.webp", "7df87dfe904e18fe", "public-domain"),
    ("explore_monuments", "france/arlesAmphitheater.webp", "62d80a80ca5e5040", "public-domain"),
    ("explore_monuments", "france/chateaudeChambord.webp", "a96693bfff66c9a7", "public-domain"),
    ("explore_monuments", "france/chateaudeChenonceau.webp", "4e414fc35ae9b4e1", "public-domain"),
    ("explore_monuments", "france/citedeCarcassonne.webp", "b9de4b334e76df53", "public-domain"),
    ("explore_monuments", "france/eiffelTower.webp", "cf115ede228937f0", "public-domain"),
    ("explore_monuments", "france/montStMichel.webp", "1c097b958c4bc0e5", "CC0-1.0"),
    ("explore_monuments", "france/palaisdesPapes.webp", "fded6367850d2faf", "CC0-1.0"),
    ("explore_monuments", "france/pontduGard.webp", "b9e560a9ae2fd919", "public-domain"),
    ("explore_monuments", "france/reimsCathedral.webp", "720ddce0a3124d68", "public-domain"),
    ("explore_monuments", "france/rocamadour.webp", "e9642c03c2300424", "public-domain"),
    ("explore_monuments", "germany/berlinCathedral.webp", "b552994f64727cea", "CC0-1.0"),
    ("explore_monuments", "germany/brandenburgGate.webp", "2cb312c79a20e0cd", "public-domain"),
    ("explore_monuments", "germany/neuschwansteinCastle.webp", "15ec5fcb8758d54e", "CC0-1.0"),
    ("explore_monuments", "germany/schwerinPalace.webp", "91be8dd19821221b", "CC0-1.0"),
    ("explore_monuments", "germany/trierImperialBaths.webp", "dd1818360d153c09", "public-domain"),
    ("explore_monuments", "germany/wormsCathedral.webp", "c90cdcbf981bcd5f", "public-domain"),
    ("explore_monuments", "india/ajantaCave.webp", "7dbf980b3711f755", "public-domain"),
    ("explore_monuments", "india/charminar.webp", "a657a2139787bded", "public-domain"),
    ("explore_monuments", "india/gatewayofIndia.webp", "8d1053776a85a970", "CC0-1.0"),
    ("explore_monuments", "india/goldenTemple.webp", "ec52355726f8c36c", "CC0-1.0"),
    ("explore_monuments", "india/greatStupa.webp", "3b6741152471d006", "public-domain"),
    ("explore_monuments", "india/hawaMahal.webp", "4edb7eed9db596bd", "public-domain"),
    ("explore_monuments", "india/konarkSunTemple.webp", "c94ddb83bb2d878f", "public-domain"),
    ("explore_monuments", "india/mysorePalace.webp", "a84a26be8d944734", "public-domain"),
    ("explore_monuments", "india/qutubMinar.webp", "dea912cbd3950dac", "CC0-1.0"),
    ("explore_monuments", "india/rangGhar.webp", "41791947f8772c9b", "public-domain"),
    ("explore_monuments", "india/victoriaMemorial.webp", "be7b3264cd3391e5", "CC0-1.0"),
    ("explore_monuments", "usa/cabrillo.webp", "e109eb44fd12f853", "CC0-1.0"),
    ("explore_monuments", "usa/canyondeChelly.webp", "2148fe45a54186a6", "public-domain"),
    ("explore_monuments", "usa/castillodeSanMarcos.webp", "b1d3584272eb66d8", "public-domain"),
    ("explore_monuments", "usa/castleClinton.webp", "c36913b06cea8917", "public-domain"),
    ("explore_monuments", "usa/fortSumter.webp", "42c8376f99f770fa", "CC0-1.0"),
    (
        "explore_monuments",
        "usa/georgeWashingtonBirthplace.webp",
        "134f44b0e1c33320",
        "public-domain",
    ),
    ("explore_monuments", "usa/lincolnMemorial.webp", "52eab4d110bd168e", "CC0-1.0"),
    ("explore_monuments", "usa/mountRushmore.webp", "d9fec7d6ac491a64", "CC0-1.0"),
    ("explore_monuments", "usa/navajo.webp", "fa8d36162b1380ac", "public-domain"),
    ("explore_monuments", "usa/statueofLiberty.webp", "8eeda3c92c734520", "public-domain"),
    ("explore_monuments", "wonders/chichenItza.webp", "9882593801be4358", "CC-BY-SA-4.0"),
    ("explore_monuments", "wonders/christTheRedeemer.webp", "3133f2872b3d7915", "CC-BY-SA-4.0"),
    ("explore_monuments", "wonders/colosseum.webp", "0d38a0c2d4910f89", "public-domain"),
    ("explore_monuments", "wonders/greatWallofChina.webp", "546e2483d17c2b73", "CC0-1.0"),
    ("explore_monuments", "wonders/machuPicchu.webp", "e04e163ccef6e594", "CC0-1.0"),
    ("explore_monuments", "wonders/petra.webp", "cc782ccdd5b50829", "public-domain"),
    ("explore_monuments", "wonders/tajMahal.webp", "fc0d45ec5a258568", "CC-BY-SA-4.0"),
    ("explore_world_animals", "animals/bison.webp", "11f3b2c5b876ee08", "CC0-1.0"),
    ("explore_world_animals", "animals/chameleon.webp", "f3ececf0133c1301", "public-domain"),
    ("explore_world_animals", "animals/crocodile.webp", "840cf54b69bf4fb9", "public-domain"),
    ("explore_world_animals", "animals/dragon.webp", "fc36683cc2069ac8", "public-domain"),
    ("explore_world_animals", "animals/giraffe.webp", "68014ed783cf6a8b", "CC0-1.0"),
    ("explore_world_animals", "animals/hedgehog.webp", "780aceaa624415db", "public-domain"),
    ("explore_world_animals", "animals/jaguar.webp", "22704727b6643480", "CC0-1.0"),
    ("explore_world_animals", "animals/kangaroo.webp", "683964b6f57fdced", "public-domain"),
    ("explore_world_animals", "animals/koala.webp", "77b243c27d79f3f5", "public-domain"),
    ("explore_world_animals", "animals/lemur.webp", "4fccf91dd5e6a749", "CC0-1.0"),
    ("explore_world_animals", "animals/moose.webp", "2252a671c2e0ade9", "public-domain"),
    ("explore_world_animals", "animals/narwhal.webp", "2a94d2fc7482ca80", "public-domain"),
    ("explore_world_animals", "animals/panda.webp", "70ccf9a9db500810", "public-domain"),
    ("explore_world_animals", "animals/polar_bear.webp", "0544cef0a7d6940d", "public-domain"),
    ("explore_world_animals", "animals/scarlet_macaw.webp", "8b088ed71a87e7e9", "CC0-1.0"),
    ("explore_farm_animals", "animals/cat.webp", "ab7c3e1b04e80bc5", "public-domain"),
    ("explore_farm_animals", "animals/chicken.webp", "30a07d3c7dfc191f", "public-domain"),
    ("explore_farm_animals", "animals/cow.webp", "db359136be5ef7c4", "public-domain"),
    ("explore_farm_animals", "animals/dog.webp", "5e9d954449574010", "public-domain"),
    ("explore_farm_animals", "animals/duck.webp", "fa4572f2022a3ade", "CC0-1.0"),
    ("explore_farm_animals", "animals/horse.webp", "87879a9644b71713", "CC0-1.0"),
    ("explore_farm_animals", "animals/owl.webp", "e8b7d705a955799f", "CC0-1.0"),
    ("explore_farm_animals", "animals/pig.webp", "4f3d27d1fd3d0b3c", "public-domain"),
    ("explore_farm_animals", "animals/sheep.webp", "3bac61d5dabb709c", "CC0-1.0"),
    ("clickgame", "sea1.webp", "a3a8c196d24f6c37", "CC0-1.0"),
    ("clickgame", "sea2.webp", "533dcc0d871a390d", "CC0-1.0"),
    ("clickgame", "sea3.webp", "9c8236a6ade2a59f", "public-domain"),
    ("clickgame", "sea4.webp", "21295e109d35b0f1", "public-domain"),
    ("clickgame", "sea5.webp", "08c6d1ae0ea47c51", "public-domain"),
    ("clickgame", "sea6.webp", "42f7a4152c54f8bf", "public-domain"),
    ("categorization", "images/alphabets/alphabets.webp", "76cdfd62ea1dde17", "CC-BY-SA-4.0"),
    ("categorization", "images/fishes/fish1.webp", "f8da0956fd2df8f9", "public-domain"),
    ("categorization", "images/fishes/fish10.webp", "9520fe60539db07e", "public-domain"),
    ("categorization", "images/fishes/fish11.webp", "3f8e2005f1a63545", "public-domain"),
    ("categorization", "images/fishes/fish12.webp", "31f7b0c655e5ee47", "public-domain"),
    ("categorization", "images/fishes/fish13.webp", "507971e48347a33d", "public-domain"),
    ("categorization", "images/fishes/fish14.webp", "87d5820ff028e03d", "public-domain"),
    ("categorization", "images/fishes/fish15.webp", "6653b505f8d74ea3", "public-domain"),
    ("categorization", "images/fishes/fish16.webp", "56ef0c2d10ecf490", "public-domain"),
    ("categorization", "images/fishes/fish19.webp", "4c5a59d1a08f9bf3", "public-domain"),
    ("categorization", "images/fishes/fish2.webp", "16e55227d9074a94", "public-domain"),
    ("categorization", "images/fishes/fish20.webp", "33f1e4dbe922e040", "public-domain"),
    ("categorization", "images/fishes/fish21.webp", "89bab44e95c35f49", "public-domain"),
    ("categorization", "images/fishes/fish22.webp", "dd5f4d25fef5927d", "public-domain"),
    ("categorization", "images/fishes/fish23.webp", "7dabcd7882e9bc7c", "public-domain"),
    ("categorization", "images/fishes/fish24.webp", "604f140322c169d0", "public-domain"),
    ("categorization", "images/fishes/fish25.webp", "a0d5498bf18d05d2", "public-domain"),
    ("categorization", "images/fishes/fish26.webp", "93f35bba996557d7", "public-domain"),
    ("categorization", "images/fishes/fish27.webp", "c6cf6e5d6a573744", "public-domain"),
    ("categorization", "images/fishes/fish3.webp", "dbfb8f788480cc8e", "public-domain"),
    ("categorization", "images/fishes/fish4.webp", "9d48365d37ee9fa2", "public-domain"),
    ("categorization", "images/fishes/fish5.webp", "f782d3ee205045e6", "public-domain"),
    ("categorization", "images/fishes/fish7.webp", "90b86f92118a24d8", "public-domain"),
    ("categorization", "images/fishes/fish8.webp", "c8a8230309b1aae6", "public-domain"),
    ("categorization", "images/fishes/fish9.webp", "c0612ddd79d51bd6", "public-domain"),
    ("categorization", "images/monuments/IndiaGate.webp", "e1baaec30c9bb850", "public-domain"),
    ("categorization", "images/monuments/arcDeTriomphe.webp", "74f0a4c82166bca6", "public-domain"),
    ("categorization", "images/monuments/bayterek.webp", "e6e367c7cc47db3f", "CC0-1.0"),
    ("categorization", "images/monuments/burj.webp", "281bbae10f981681", "public-domain"),
    ("categorization", "images/monuments/cathedral.webp", "4b7cfd9b6affec5b", "public-domain"),
    ("categorization", "images/monuments/empireState.webp", "47f7d88344ae2ee0", "CC0-1.0"),
    ("categorization", "images/monuments/leMusee.webp", "dea8ecafefc9e596", "CC0-1.0"),
    (
        "categorization",
        "images/monuments/leaningTowerOfPisa.webp",
        "7b12550a377ace9f",
        "public-domain",
    ),
    ("categorization", "images/monuments/monument1.webp", "d59b1a3dfe791f44", "CC0-1.0"),
    ("categorization", "images/monuments/monument2.webp", "7587bf65bdda88e4", "public-domain"),
    ("categorization", "images/monuments/monument3.webp", "2aeae153a07ab38f", "CC0-1.0"),
    ("categorization", "images/monuments/operaHouse.webp", "56471309ddfa80c6", "CC0-1.0"),
    ("categorization", "images/monuments/parthenon.webp", "8be7349b09f901ff", "CC0-1.0"),
    ("categorization", "images/monuments/usCapitol.webp", "eefead4c662541df", "CC0-1.0"),
    ("categorization", "images/monuments/zimniPalace.webp", "52899efd8e7adc21", "public-domain"),
    ("categorization", "images/numbers/numbers.webp", "9bee0d3330c34f97", "CC-BY-SA-4.0"),
    ("categorization", "images/others/baseball.webp", "374c9ed08f3aef66", "public-domain"),
    ("categorization", "images/others/bucket.webp", "671363d9d02c1276", "CC0-1.0"),
    ("categorization", "images/others/bulb.webp", "e83dc5d256f1daa7", "CC0-1.0"),
    ("categorization", "images/others/chair.webp", "493bce8a8060d788", "public-domain"),
    ("categorization", "images/others/igloo.webp", "c711e77a0e92ec82", "CC0-1.0"),
    ("categorization", "images/others/pillow.webp", "ee41fef3908ad653", "CC0-1.0"),
    ("categorization", "images/others/spoons.webp", "496b5e1d19165dd4", "public-domain"),
    ("categorization", "images/others/volleyball.webp", "33bfa2aa2d236679", "public-domain"),
    ("categorization", "images/others/weighingMachine.webp", "c5ab1633cc4e4b31", "public-domain"),
    ("categorization", "images/renewable/dam1.webp", "80fac341dc858de1", "public-domain"),
    ("categorization", "images/renewable/dam2.webp", "551713016f437171", "public-domain"),
    ("categorization", "images/renewable/dam3.webp", "f0e75c317c86f29e", "public-domain"),
    ("categorization", "images/renewable/dam4.webp", "e62de656200a81c4", "CC0-1.0"),
    ("categorization", "images/renewable/dam5.webp", "b4ae23f5257dca05", "public-domain"),
    ("categorization", "images/renewable/solar1.webp", "e356d9ea25f1e390", "CC0-1.0"),
    ("categorization", "images/renewable/solar2.webp", "a23a44657f6b5ef0", "CC0-1.0"),
    ("categorization", "images/renewable/solar3.webp", "0556ddf649640b42", "public-domain"),
    ("categorization", "images/renewable/solar4.webp", "bd850c3e9227c5bb", "public-domain"),
    ("categorization", "images/renewable/solar5.webp", "32ab92f9339debc8", "CC0-1.0"),
    ("categorization", "images/renewable/solar6.webp", "920ba181909040dd", "public-domain"),
    ("categorization", "images/renewable/solar7.webp", "5118a3f9ea3fb8a3", "CC0-1.0"),
    ("categorization", "images/renewable/solar8.webp", "7e9351711374c1c6", "public-domain"),
    ("categorization", "images/renewable/windmill.webp", "f88eafdf15746408", "public-domain"),
    ("categorization", "images/renewable/windmill1.webp", "b37b659aa07d8858", "CC0-1.0"),
    ("categorization", "images/renewable/windmill11.webp", "2587476c5392f61c", "CC0-1.0"),
    ("categorization", "images/renewable/windmill12.webp", "6fcf82fd1da0dc01", "public-domain"),
    ("categorization", "images/renewable/windmill13.webp", "c4f9425d5b98186a", "CC0-1.0"),
    ("categorization", "images/renewable/windmill15.webp", "670d8ac8507ea1ab", "CC0-1.0"),
    ("categorization", "images/renewable/windmill2.webp", "e624eec1215008b2", "public-domain"),
    ("categorization", "images/renewable/windmill3.webp", "da254fb000c28e2c", "public-domain"),
    ("categorization", "images/renewable/windmill4.webp", "71ec7ff549a87280", "CC0-1.0"),
    ("categorization", "images/renewable/windmill5.webp", "c6c35dbdbc5aee60", "CC0-1.0"),
    ("categorization", "images/renewable/windmill7.webp", "6f922d01319baea5", "public-domain"),
    ("categorization", "images/renewable/windmill8.webp", "c2b2e776f9104977", "CC0-1.0"),
    ("categorization", "images/renewable/windmill9.webp", "b182d59c8dc8aef1", "CC0-1.0"),
    ("categorization", "images/tools/cuttingTool.webp", "e6c0c0bd69550be6", "public-domain"),
    ("categorization", "images/tools/hammer3.webp", "e38ac01ccfc0af53", "CC0-1.0"),
    ("categorization", "images/tools/hammer4.webp", "c3b04b4d9d6264b8", "CC0-1.0"),
    ("categorization", "images/tools/hammer5.webp", "1f4a276ac27a8136", "public-domain"),
    ("categorization", "images/tools/multimeter1.webp", "5c43683f2fc83fb8", "public-domain"),
    ("categorization", "images/tools/multimeter2.webp", "536f3a4e18f01f7c", "public-domain"),
    ("categorization", "images/tools/multimeter3.webp", "98fe7d81dc12f7a1", "public-domain"),
    ("categorization", "images/tools/nailCutter.webp", "ac327299a1796b6d", "public-domain"),
    ("categorization", "images/tools/plier1.webp", "a7bf094e741e5523", "public-domain"),
    ("categorization", "images/tools/plier3.webp", "ce71f32fdb241779", "public-domain"),
    ("categorization", "images/tools/scissors2.webp", "ebea0e41fbab5b01", "public-domain"),
    ("categorization", "images/tools/scissors3.webp", "1367627b89e4c5aa", "CC0-1.0"),
    ("categorization", "images/tools/screwDriver1.webp", "8ca5030b12163c5c", "public-domain"),
    ("categorization", "images/tools/sickle.webp", "c14aa994c6f9b486", "public-domain"),
    ("categorization", "images/tools/sideCutter1.webp", "234ce8d0b67e3f29", "public-domain"),
    ("categorization", "images/tools/spray.webp", "c63a0145cf7e0fdb", "CC0-1.0"),
    ("categorization", "images/tools/tweezer.webp", "7d67460c11f30bc7", "CC0-1.0"),
    ("categorization", "images/tools/wrench1.webp", "b1c6e3efdf2018fc", "public-domain"),
    ("explore_world_music", "music/africa.webp", "c4b27aebe08498a8", "public-domain"),
    ("explore_world_music", "music/america.webp", "72af64588442d1e2", "CC-BY-2.0"),
    ("explore_world_music", "music/australia.webp", "b7e0bc6da6f9fd8b", "CC-BY-2.0"),
    ("explore_world_music", "music/ireland.webp", "20ef5a10a55b0363", "CC-BY-2.0"),
    ("explore_world_music", "music/italy.webp", "b30a023e5d36bb05", "CC0-1.0"),
    ("explore_world_music", "music/japan.webp", "0f0aa2d3116e01ac", "public-domain"),
    ("explore_world_music", "music/mexico.webp", "cd1286e5d7649bc4", "CC0-1.0"),
    ("explore_world_music", "music/middleeast.webp", "bc847e52730f5920", "CC0-1.0"),
    ("explore_world_music", "music/orchestra.webp", "b4a6d85a40cefbd3", "public-domain"),
]
#: Package folder, folder of the photographs in it, licence, and (stem, SHA-256 prefix).
_FILES = [
    (
        "kphotoalbum",
        "usr/share/kphotoalbum/demo",
        "GPL-2+",
        [
            ("anne_helene", "75dea938bf86530e"),
            ("bar55", "dd57f8a93ea84b46"),
            ("bar55_2", "e2a3ebc63306abf0"),
            ("blackie", "5a72fc60a65448e0"),
            ("cold_water", "1c92d77426301289"),
            ("donna", "c98f91990752bb6d"),
            ("donna_2", "b476b81f11db4067"),
            ("grand_canyon_1", "5d60136f1143918c"),
            ("grand_canyon_2", "7814adbefb9665f5"),
            ("grand_canyon_3", "923ba3a8d1699338"),
            ("jesper", "5b3b5a6cdf040c23"),
            ("jesper_2", "e7c5112cad4076c0"),
            ("new_wave_1", "dd422c963594e044"),
            ("new_wave_2", "a262d1ec436c0f41"),
            ("pool", "c6b1c79236388d3a"),
            ("pool_2", "82f0e4ec1906a55b"),
            ("qt-logo", "12f4d580dff54dab"),
            ("skagen", "d7c724e47d68b9f9"),
            ("skagen_2", "17ca43c9fb3b60ad"),
            ("snow", "7106574608681e7e"),
            ("spiff", "4d222fe255566ab7"),
            ("spiff_2", "9bbab84f204329e1"),
            ("sunset", "da4a44a03272bbaa"),
            ("wayne", "1e5e3880f65a8571"),
        ],
    ),
    (
        "tuxpaint",
        "usr/share/tuxpaint/templates",
        "GPL-2+",
        [
            ("burnt_bark", "14f3d6ad3fa5dd2c"),
            ("cliff", "ff8da5b7a4eb5f55"),
            ("corn_maze", "e3c5dfd777c38fbf"),
            ("jellyfish", "340228d440273706"),
            ("lighthouse", "bf92c1139da97690"),
            ("mossy_bark", "153b9d8eb33c6f0f"),
            ("mossy_log", "02ba4842fcf5f48f"),
            ("mudstone", "ce1d13d3b66155be"),
            ("ocean_splash", "a6c1697ed8dc06c7"),
            ("ocean_waves", "b99c24c7148cb293"),
            ("redwoods_above", "cda5f9d27e979e01"),
            ("rocks", "f3ddf517f26bc77a"),
            ("sheep", "cb408f8b3fc32479"),
            ("spiders_web", "a105461c86ff3c61"),
            ("sun_behind_clouds", "a76583449fb6cf58"),
            ("sun_behind_leaves", "a6373334dc5af701"),
            ("trees_above", "d75bcb1c0c9cd3f9"),
            ("trees_at_dusk", "9499116f8e8f494b"),
            ("wool_mill_machine", "e66d36c482d32cc5"),
        ],
    ),
    (
        "palapeli",
        "usr/share/palapeli/collection",
        "GPL-2+",
        [
            ("castle-maintenon", "f4a6bf48b97d9771"),
            ("cincinnati-bridge", "09772d09318b34a5"),
            ("citrus-fruits", "0cbd7154a1478980"),
            ("european-honey-bee", "9d54ae706bddd899"),
            ("panther-chameleon-female", "adb9e2834a8a3db4"),
        ],
    ),
    (
        "lomiri-20.04",
        "usr/share/backgrounds",
        "CC-BY-SA-3.0",
        [
            ("Kleiber_by_Lukas_Baubkus", "6572410c09f4492c"),
        ],
    ),
    (
        "mate",
        "usr/share/backgrounds/mate/nature",
        "GPL-2+",
        [
            ("Garden", "d3095ee09d425ef2"),
            ("LadyBird", "e35a9a4126ef969c"),
            ("YellowFlower", "254da96256acb7ad"),
        ],
    ),
]

_NEW = [
    (_gcompris(activity, path, sha256), licence) for activity, path, sha256, licence in _GCOMPRIS
] + [
    (_file(package, folder, stem, sha256), licence)
    for package, folder, licence, files in _FILES
    for stem, sha256 in files
]
#: The licence of every photograph added by the extended set, by name.
LICENCES = {photo.name: licence for photo, licence in _NEW}
#: The photographer and source of every photograph whose licence asks for
#: attribution (CC-BY and CC-BY-SA), from upstream's README beside it.
ATTRIBUTION = {
    "lomiri-20.04/Kleiber_by_Lukas_Baubkus": (
        "Lukas Baubkus",
        "Ubuntu Touch 20.04 wallpapers (lomiri-wallpapers-20.04 20.04.0-2)",
    ),
    "gcompris/categorization/images/alphabets/alphabets": (
        "Divyam Madaan",
        "GCompris (gcompris-qt-data 3.1-2)",
    ),
    "gcompris/categorization/images/numbers/numbers": (
        "Divyam Madaan",
        "GCompris (gcompris-qt-data 3.1-2)",
    ),
    "gcompris/erase/alpaca": (
        "Dietmar Rabich",
        "https://commons.wikimedia.org/wiki/File:D%C3%BClmen,_B%C3%B6rnste,_Alpakas_--_2020_--_5338.jpg",
    ),
    "gcompris/erase/bee": (
        "aussiegall",
        "https://commons.wikimedia.org/wiki/File:Pollinationn.jpg",
    ),
    "gcompris/erase/butterfly": (
        "Jee & Rani Nature Photography",
        "https://commons.wikimedia.org/wiki/File:Parantica_aglea_at_Nayikayam_Thattu.jpg",
    ),
    "gcompris/erase/calf": (
        "Basile Morin",
        "https://commons.wikimedia.org/wiki/File:Close-up_photograph_of_a_calf%27s_head_looking_at_the_viewer_with_pricked_ears_in_Don_Det_Laos.jpg",
    ),
    "gcompris/erase/camels": (
        "Alexandr frolov",
        "https://commons.wikimedia.org/wiki/File:Camelus_bactrianus_in_western_Mongolia_02.jpg",
    ),
    "gcompris/erase/caterpillar": (
        "Ivar Leidus",
        "https://commons.wikimedia.org/wiki/File:Papilio_machaon_-_Daucus_carota_-_Keila.jpg",
    ),
    "gcompris/erase/chamaeleon": (
        "Benny Trapp",
        "https://commons.wikimedia.org/wiki/File:BennyTrapp_Chamaeleo_chamaeleon_Samos_Griechenland.jpg",
    ),
    "gcompris/erase/cheetah": (
        "Charles J. Sharp",
        "https://commons.wikimedia.org/wiki/File:Cheetah_(Acinonyx_jubatus)_female_2.jpg",
    ),
    "gcompris/erase/dolphin": (
        "טל שמע",
        "https://commons.wikimedia.org/wiki/File:Eilat_Dolphin_Reef_(3).jpg",
    ),
    "gcompris/erase/flying_fox": (
        "Andrew Mercer",
        "https://commons.wikimedia.org/wiki/File:Grey_headed_flying_fox_-_AndrewMercer_IMG41848.jpg",
    ),
    "gcompris/erase/gibbon": (
        "JJ Harrison",
        "https://commons.wikimedia.org/wiki/File:Hylobates_lar_-_Kaeng_Krachan_WB.jpg",
    ),
    "gcompris/erase/goat": (
        "JoachimKohlerBremen",
        "https://commons.wikimedia.org/wiki/File:Walliser_Schwarzhalsziege,_Belalp_2014.jpg",
    ),
    "gcompris/erase/gorilla": (
        "Charles J. Sharp",
        "https://commons.wikimedia.org/wiki/File:Mountain_gorilla_(Gorilla_beringei_beringei)_female_2.jpg",
    ),
    "gcompris/erase/gosling": (
        "Stephan Sprinz",
        "https://commons.wikimedia.org/wiki/File:Graugans-G%C3%B6ssel_(anser_anser)_im_Naturschutzgebiet_Wagbachniederung.jpg",
    ),
    "gcompris/erase/heron": (
        "Stephan Sprinz",
        "https://commons.wikimedia.org/wiki/File:Purpurreiher_(ardea_purpurea)_im_Flug_-_NSG_Wagbachniederung_1.jpg",
    ),
    "gcompris/erase/horse": (
        "Eatcha",
        "https://commons.wikimedia.org/wiki/File:Zaniskari_Horse_in_Ladakh.jpg",
    ),
    "gcompris/erase/kitten": (
        "GalgenTX",
        "https://commons.wikimedia.org/wiki/File:A_posing_kitten_(Flickr).jpg",
    ),
    "gcompris/erase/long_nosed_monkey": (
        "Charles J. Sharp",
        "https://commons.wikimedia.org/wiki/File:Proboscis_monkey_(Nasalis_larvatus)_female_and_baby.jpg",
    ),
    "gcompris/erase/macaque": (
        "PJeganathan",
        "https://commons.wikimedia.org/wiki/File:Bonnet_macaques_in_anaimalai_hills_JEG2730.jpg",
    ),
    "gcompris/erase/meerkats": (
        "Charles J. Sharp",
        "https://commons.wikimedia.org/wiki/File:Meerkat_(Suricata_suricatta)_Tswalu.jpg",
    ),
    "gcompris/erase/northern_harrier": (
        "Frank Schulenburg",
        "https://commons.wikimedia.org/wiki/File:Female_northern_harrier_in_flight-1142.jpg",
    ),
    "gcompris/erase/nubian_ibex": (
        "Rhododendrites",
        "https://commons.wikimedia.org/wiki/File:Juvenile_Nubian_ibex_in_Mitzpe_Ramon_(40409).jpg",
    ),
    "gcompris/erase/penguin": (
        "Gordon Leggett",
        "https://commons.wikimedia.org/wiki/File:2019-03-03_Chinstrap_penguin_on_Barrientos_Island,_Antarctica.jpg",
    ),
    "gcompris/erase/rhinoceros": (
        "Charles J. Sharp",
        "https://commons.wikimedia.org/wiki/File:Indian_rhinoceros_(Rhinoceros_unicornis)_4.jpg",
    ),
    "gcompris/erase/spoonbills": (
        "Ryzhkov Sergey",
        "https://commons.wikimedia.org/wiki/File:%D0%9A%D0%BE%D1%81%D0%B0%D1%80%D1%96_%D0%B2_%D0%B4%D0%B5%D0%BB%D1%8C%D1%82%D1%96_%D0%94%D1%83%D0%BD%D0%B0%D1%8E.jpg",
    ),
    "gcompris/erase/squirrel": (
        "Роман Наумов",
        "https://commons.wikimedia.org/wiki/File:%D0%91%D1%96%D0%BB%D0%BA%D0%B0_%D0%BD%D0%B0_%D0%B4%D0%B5%D1%80%D0%B5%D0%B2%D1%96_%D0%B2_%D0%B4%D0%B5%D0%BD%D0%B4%D1%80%D0%BE%D0%BF%D0%B0%D1%80%D0%BA%D1%83_%D0%9E%D0%BB%D0%B5%D0%BA%D1%81%D0%B0%D0%BD%D0%B4%D1%80%D1%96%D1%8F.jpg",
    ),
    "gcompris/erase/swans": (
        "Charles J. Sharp",
        "https://commons.wikimedia.org/wiki/File:Mute_swans_(Cygnus_olor)_and_cygnets.jpg",
    ),
    "gcompris/erase/toucan": (
        "LG Nyqvist",
        "https://commons.wikimedia.org/wiki/File:Pteroglossus_torquatus_Costa_Rica.jpg",
    ),
    "gcompris/explore_monuments/wonders/chichenItza": (
        "Daniel Schwen",
        "https://commons.wikimedia.org/wiki/File:Chichen_Itza_3.jpg",
    ),
    "gcompris/explore_monuments/wonders/christTheRedeemer": (
        "Chensiyuan",
        "https://commons.wikimedia.org/wiki/File:1_cristor_redentor_2014.jpg",
    ),
    "gcompris/explore_monuments/wonders/tajMahal": (
        "Yann",
        "https://commons.wikimedia.org/wiki/File:Taj_Mahal,_Agra,_India.jpg",
    ),
    "gcompris/explore_world_music/music/america": (
        "Tom Harpel",
        "https://commons.wikimedia.org/wiki/File:Onalaska-Practice6.jpg",
    ),
    "gcompris/explore_world_music/music/australia": (
        "Steve Evans",
        "https://commons.wikimedia.org/wiki/File:Australia_Aboriginal_Culture_009.jpg",
    ),
    "gcompris/explore_world_music/music/ireland": (
        "candyschwartz",
        "https://commons.wikimedia.org/wiki/File:Lunny_irvine_o_flynn_glackin.jpg",
    ),
}
_HELD_OUT_NAMES = {
    "gcompris/erase/toucan",
    "gcompris/explore_monuments/wonders/petra",
    "gcompris/categorization/images/renewable/windmill3",
    "tuxpaint/rocks",
    "kphotoalbum/skagen",
    "palapeli/citrus-fruits",
}
#: Today's raisr photographs and the new ones, less the held-out ones.
EXTENDED = [*TRAINING, *(photo for photo, _ in _NEW if photo.name not in _HELD_OUT_NAMES)]
#: Photographs never trained on: today's three and six new ones.
EXTENDED_HELD_OUT = [*HELD_OUT, *(photo for photo, _ in _NEW if photo.name in _HELD_OUT_NAMES)]
