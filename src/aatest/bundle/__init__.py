"""The signed bundle: what a certificate's signature covers, and how a verifier checks it.

A run's report directory (report, ``results.json``, ``recording.mcap``, ``run_state.json``,
``steps/*.mcap``) is a bundle; it is signed once it is complete and verified wherever it is read
(``aatest verify``, the records store, the station).

- ``manifest``      what a signature covers: the SHA-256 of every file, and what is left out why
- ``signing``       Ed25519 keys and the detached signature file ``<report>.sig``
- ``trust``         which keys a verifier trusts (the lab's, by fingerprint and validity period)
- ``verification``  intact files, a valid signature and a trusted key, each with named reasons
- ``observers``     who is told before a bundle's results are written and once it is signed
                    (the records store, installed by the CLI)

The engine's session signs a bundle at the end of a run (:mod:`aatest.engine.run.session`);
nothing here runs a plugin or reads a recording's contents.
"""
