"""The gateway's tokens, each with a role and maybe a name, and the token file that holds them.

A token file holds one `ROLE TOKEN [NAME]` line per token; blank lines and comments (from a
word that starts with `#` to the end of its line) are skipped. A file whose only line is one
bare token (the format of old) holds an admin token without a name. Every token, in either
format, has at least TOKEN_MIN_CHARACTERS characters (core/bounds.py) and is given once, and
every name once; a role word is one of ROLES, and a bare token may not begin with one joined
to it (`viewer=TOKEN` would be an admin's). A line that cannot be read stops the gateway with
its line number; no message ever shows a token.
"""

import enum
import hashlib
import logging
import re
import secrets
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path

from task_manager.core.bounds import TOKEN_MIN_CHARACTERS
from task_manager.core.sources import SOURCE_NAME, SOURCE_NAME_RULE
from task_manager.gateway.secret_file import exposure_warning

GENERATED_NAME = 'admin'
"""The name of the token the gateway makes when it is given no token file."""
ADMIN_TOKEN_VARIABLE = 'TASK_MANAGER_WEB_ADMIN_TOKEN'
"""The admin token of a gateway given no token file, instead of one made at its start: a
launcher that starts the gateway again gives the new one the token the dashboard holds."""
NAME = SOURCE_NAME
"""A token's name: it ends up in the source of every task the token starts (`WEB:alice`)."""
TOKEN = re.compile(r'[!-~]+')
"""A token: printable ASCII without spaces (an HTTP header carries it)."""
LINE_FORMAT = 'ROLE TOKEN [NAME]'
JOINED_ROLE = re.compile(r'(?i)(viewer|operator|admin)[=:,;]')
"""A bare token that begins with a role word and a separator: a `ROLE TOKEN` line mistyped."""


class Role(enum.IntEnum):
    """What a token may do; each role may do what the roles below it may."""

    VIEWER = 1
    """Read: the declared, active and ended tasks, the schedules, the events, the metrics."""
    OPERATOR = 2
    """Also start tasks and missions, cancel, stop, pause, resume, confirm."""
    ADMIN = 3
    """Also change the schedules and the priorities (a start that gives one, reprioritize)."""

    @property
    def label(self) -> str:
        """As written in a token file and in the API: `viewer`, `operator`, `admin`."""
        return self.name.lower()


ROLES = {role.label: role for role in Role}
"""key: a role as written in a token file, value: the role."""


@dataclass(frozen=True)
class Token:
    """One token of the gateway."""

    secret: str
    role: Role
    name: str = ''
    """The holder's name, in the source of what the token starts; '': none."""

    @property
    def key(self) -> str:
        """The holder as a client of the read bound: its name, else a hash of the token."""
        if self.name:
            return f'token:{self.name}'
        return f'token-sha256:{hashlib.sha256(self.secret.encode()).hexdigest()[:16]}'


class TokenFileError(Exception):
    """A token file that cannot be read; the message names the line, never a token."""


def generated_token() -> Token:
    """A new random admin token named `admin` (for a gateway given no token file)."""
    return Token(secrets.token_urlsafe(24), Role.ADMIN, GENERATED_NAME)


def read_token_file(path: Path) -> tuple[Token, ...]:
    """The tokens of the file at `path`."""
    try:
        text = path.read_text()
    except (OSError, UnicodeDecodeError) as error:
        raise TokenFileError(f'cannot read {path}: {error}') from None
    return parse_tokens(text, str(path))


def parse_tokens(text: str, where: str) -> tuple[Token, ...]:
    """The tokens of a token file's `text`; `where` names the file in messages."""
    lines = [(number, words) for number, words in _words(text.splitlines()) if words]
    if not lines:
        raise TokenFileError(f'{where} holds no token: write one `{LINE_FORMAT}` line per token')
    if len(lines) == 1 and len(lines[0][1]) == 1:
        number, (secret,) = lines[0]
        return (_bare_token(secret, where, number),)
    tokens = tuple(_token(words, where, number) for number, words in lines)
    _check_unique(tokens, [number for number, _ in lines], where)
    return tokens


def _words(lines: Iterable[str]) -> Iterable[tuple[int, list[str]]]:
    """Each line's number (from 1) and its words before a comment."""
    for number, line in enumerate(lines, start=1):
        words = line.split()
        comment = next((i for i, word in enumerate(words) if word.startswith('#')), len(words))
        yield number, words[:comment]


def _bare_token(secret: str, where: str, number: int) -> Token:
    """The admin token of a file whose only line is one word."""
    if secret in ROLES:
        raise TokenFileError(f'{where}, line {number}: a role without a token')
    if joined := JOINED_ROLE.match(secret):
        raise TokenFileError(
            f'{where}, line {number}: a role word joined to a token by {joined[0][-1]!r} would '
            f"be one bare token, an admin's; write `{LINE_FORMAT}`, the words apart"
        )
    return Token(_checked_secret(secret, where, number), Role.ADMIN)


def _token(words: list[str], where: str, number: int) -> Token:
    if len(words) not in (2, 3):
        raise TokenFileError(
            f'{where}, line {number}: {len(words)} words; expected `{LINE_FORMAT}` (a bare '
            'token is read only when it is the only line of the file)'
        )
    role = ROLES.get(words[0])
    if role is None:
        raise TokenFileError(
            f'{where}, line {number}: the first word is no role; roles: {", ".join(ROLES)}'
        )
    name = words[2] if len(words) == 3 else ''
    if name and not NAME.fullmatch(name):
        raise TokenFileError(f'{where}, line {number}: a name is {SOURCE_NAME_RULE}')
    return Token(_checked_secret(words[1], where, number), role, name)


def _checked_secret(secret: str, where: str, number: int) -> str:
    if not TOKEN.fullmatch(secret):
        raise TokenFileError(
            f'{where}, line {number}: a token is printable ASCII characters without spaces'
        )
    if len(secret) < TOKEN_MIN_CHARACTERS:
        raise TokenFileError(
            f'{where}, line {number}: the token has {len(secret)} characters; at least '
            f'{TOKEN_MIN_CHARACTERS} are needed (make one: python3 -c "import secrets; '
            'print(secrets.token_urlsafe(24))")'
        )
    return secret


def _check_unique(tokens: tuple[Token, ...], numbers: list[int], where: str) -> None:
    """One line per token, and per name: the same token twice would have two roles or names,
    the same name twice would make two holders one in the history (`WEB:alice`)."""
    token_line: dict[str, int] = {}  # key: a token, value: the number of its first line
    name_line: dict[str, int] = {}  # key: a name, value: the number of its first line
    for token, number in zip(tokens, numbers, strict=True):
        if token.secret in token_line:
            raise TokenFileError(
                f'{where}, line {number}: the same token as line {token_line[token.secret]}'
            )
        if token.name in name_line:
            raise TokenFileError(
                f'{where}, line {number}: the same name as line {name_line[token.name]}; '
                "each name is one holder's"
            )
        token_line[token.secret] = number
        if token.name:
            name_line[token.name] = number


def door_tokens(
    program: str, token_file: Path | None, environ: Mapping[str, str] | None = None
) -> tuple[Token, ...]:
    """The tokens of a door (`program`'s): those of `token_file`, else an admin's, that of
    ADMIN_TOKEN_VARIABLE in `environ` (the web gateway's environment) or one made here;
    SystemExit naming the line when the file cannot be read (or the variable's token is no
    token), a warning logged when other users may read the file."""
    if token_file is None:
        given = (environ or {}).get(ADMIN_TOKEN_VARIABLE, '')
        if not given:
            return (generated_token(),)
        if not TOKEN.fullmatch(given) or len(given) < TOKEN_MIN_CHARACTERS:
            raise SystemExit(
                f'{program}: {ADMIN_TOKEN_VARIABLE} is no token: at least '
                f'{TOKEN_MIN_CHARACTERS} printable ASCII characters without spaces'
            )
        return (Token(given, Role.ADMIN, GENERATED_NAME),)
    try:
        tokens = read_token_file(token_file)
    except TokenFileError as error:
        raise SystemExit(f'{program}: --token-file {error}') from None
    if warning := exposure_warning(token_file):
        logging.getLogger(program).warning(f'--token-file {warning}')
    return tokens


def dashboard_line(url: str, tokens: tuple[Token, ...], token_file: Path | None) -> str:
    """The dashboard's link: with the token made here, else how to open it."""
    if token_file is None:
        return f'dashboard: {url}?token={tokens[0].secret}'
    roles = ', '.join(
        f'{sum(t.role is role for t in tokens)} {role.label}'
        for role in sorted({t.role for t in tokens}, reverse=True)
    )
    return f'dashboard: {url} (open it with ?token=TOKEN, a token of {token_file}: {roles})'
