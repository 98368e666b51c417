"""Every error the gateway answers is JSON: `{"error": {"code", "message", "field"}}`.

Never a traceback to the client: an unexpected exception is one log line and a 500.
"""

import logging
from collections.abc import Mapping

from fastapi import FastAPI, Request
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse
from starlette.exceptions import HTTPException

from task_manager.core.errors import TaskManagerUnavailable
from task_manager.protocol.errors import RefusalCode, describe

LOG = logging.getLogger('task_manager_web')
# key: HTTP status of Starlette's own errors, value: our code for it
_HTTP_CODES = {
    401: RefusalCode.UNAUTHORIZED,
    404: RefusalCode.NOT_FOUND,
    405: RefusalCode.METHOD_NOT_ALLOWED,
    413: RefusalCode.BODY_TOO_LARGE,
}
# the parts of a request's error locations that name no field
REQUEST_PARTS = ('body', 'query', 'path')


class ApiError(Exception):
    """An answer other than success, with its HTTP status."""

    def __init__(
        self,
        status: int,
        code: str,
        message: str,
        field: str = '',
        headers: Mapping[str, str] | None = None,
    ) -> None:
        super().__init__(message)
        self.status = status
        self.code = code
        self.message = message
        self.field = field
        self.headers = headers


def error_response(
    status: int, code: str, message: str, field: str = '', headers: Mapping[str, str] | None = None
) -> JSONResponse:
    body = {'error': {'code': code, 'message': message, 'field': field}}
    return JSONResponse(body, status_code=status, headers=headers)


async def _on_validation_error(_: Request, error: Exception) -> JSONResponse:
    assert isinstance(error, RequestValidationError)
    errors = list(error.errors())
    message, field = describe(errors, skip=REQUEST_PARTS)
    if message == 'the message must be a JSON object':
        message = 'the body must be a JSON object, sent with Content-Type: application/json'
    if errors[0].get('type') == 'extra_forbidden' and field == 'source':
        message = (
            'source: set by the gateway (the tasks started here are its own, WEB by default), '
            'not by the request: leave it out'
        )
    return error_response(422, RefusalCode.INVALID_REQUEST, message, field)


async def _on_api_error(_: Request, error: Exception) -> JSONResponse:
    assert isinstance(error, ApiError)
    return error_response(error.status, error.code, error.message, error.field, error.headers)


async def _on_unavailable(_: Request, error: Exception) -> JSONResponse:
    return error_response(503, RefusalCode.TASK_MANAGER_UNAVAILABLE, str(error))


async def _on_http_error(_: Request, error: Exception) -> JSONResponse:
    assert isinstance(error, HTTPException)
    code = _HTTP_CODES.get(error.status_code, f'http_{error.status_code}')
    return error_response(error.status_code, code, str(error.detail), headers=error.headers)


async def _on_unexpected(request: Request, error: Exception) -> JSONResponse:
    LOG.error('%s %s failed: %s: %s', request.method, request.url.path, type(error).__name__, error)
    return error_response(
        500, RefusalCode.INTERNAL_ERROR, f'the gateway failed: {type(error).__name__}'
    )


def add_error_handlers(app: FastAPI) -> None:
    app.add_exception_handler(RequestValidationError, _on_validation_error)
    app.add_exception_handler(ApiError, _on_api_error)
    app.add_exception_handler(TaskManagerUnavailable, _on_unavailable)
    app.add_exception_handler(HTTPException, _on_http_error)
    app.add_exception_handler(Exception, _on_unexpected)
